//! Training the WildLight model (SPEC §2, §4): an SDF field, a material
//! field and an ambient radiance field, rendered with NeuS and a physically
//! modelled flash, fitted to flash and no-flash photographs.
//!
//! - [`config`]: every setting, with defaults, TOML in and out;
//! - [`retired`]: the settings of experiments that were not kept, which a
//!   configuration may still name;
//! - [`model`]: the fields and scalars, and their gradients;
//! - [`rays`]: drawing training rays across all images;
//! - [`pipeline`]: one differentiable pass over a batch of rays;
//! - [`ambient`]: the ambient term of a pass, in its two forms;
//! - [`background`]: the background beyond the unit sphere of a run without
//!   masks (SPEC §6);
//! - [`loss`]: the losses of SPEC §4;
//! - [`smoothness`]: a smoothness prior on the material field;
//! - [`normal_smoothness`]: a smoothness prior on the normals;
//! - [`metallic_prior`]: a prior pushing metallic towards 0 or 1;
//! - [`visual_hull`]: the masks' visual hull and a prior keeping the SDF
//!   positive outside it (no floaters);
//! - [`trainer`]: the optimisation step, checkpoints;
//! - [`averaging`]: the mean of the parameters over a run's last part;
//! - [`render_view`]: rendering whole views and their maps;
//! - [`preview`]: preview images;
//! - [`run`]: the run folder and the training loop behind `wildlight train`.

pub mod ambient;
pub mod averaging;
pub mod background;
pub mod bench;
pub mod config;
pub mod float;
pub mod inference;
pub mod loss;
pub mod metallic_prior;
pub mod model;
pub mod normal_smoothness;
pub mod pipeline;
pub mod preview;
pub mod rays;
pub mod render_view;
pub mod retired;
pub mod run;
pub mod smoothness;
pub mod support;
pub mod trainer;
pub mod visual_hull;

pub use config::TrainConfig;
pub use model::Model;
pub use trainer::{StepStats, StepTimes, Trainer};
