//! Synthetic flash/no-flash captures with ground truth (`wildlight synth`).
//!
//! A capture is an object (a built-in procedural scene meshed from its
//! signed distance function, or a mesh file), a spatially varying material
//! given as a function of position, a ring of cameras, an environment light
//! integrated by Monte Carlo with shadows, and for flash views the exact
//! flash term of SPEC §2 ([`render`], shading with the path tracer of
//! `wildlight-pathtrace`). The output is a
//! dataset folder in the layout of SPEC §5, behind the object the room,
//! a table top or nothing ([`background`]), with per-view ground-truth maps,
//! the ground-truth meshes and `gt/material.json`, from which
//! [`GroundTruthMaterial`] evaluates the true material at any point.
//!
//! ```no_run
//! use wildlight_synth::{synthesize, SynthOptions};
//! let opts = SynthOptions { out: "capture".into(), ..SynthOptions::default() };
//! let summary = synthesize(&opts).unwrap();
//! println!("{} views written to {}", summary.train_views, summary.out.display());
//! ```

// `!(x > 0.0)` is used on purpose: it also rejects NaN.
#![allow(clippy::neg_cmp_op_on_partial_ord)]

pub mod background;
pub mod capture;
pub mod error;
pub mod ground_truth;
pub mod mesher;
pub mod render;
pub mod rig;
pub mod scenes;
pub mod sdf;

pub use background::{Background, BackgroundInfo, BackgroundKind, Table};
pub use capture::{
    CaptureSummary, DEFAULT_SATURATION, SceneSource, SynthOptions, scene_mesh, synthesize,
};
pub use error::SynthError;
pub use ground_truth::{GroundTruthMaterial, MaterialDefinition};
pub use render::{RenderScene, ShadingSettings, ViewImages, render_view};
pub use rig::{RigOptions, RigView, Split};
pub use scenes::BuiltinScene;
