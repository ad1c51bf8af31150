//! Asset export (SPEC §9): from an SDF and a material field to a textured
//! PBR asset — glTF 2.0 binary and OBJ + MTL + PNG — plus reading an
//! exported `.glb` back, rendering it under its capture's flash and an
//! environment light, and measuring the round trip (flash term and
//! eq. 16 reference surface).
//!
//! ```no_run
//! use wildlight_export::{AnalyticSource, ExportOptions, export_to_dir};
//! let sphere = AnalyticSource::new(|p: glam::Vec3| p.length() - 0.5, |_| [0.5; 9]);
//! let (files, report) = export_to_dir(&sphere, &ExportOptions::default(), "out".as_ref()).unwrap();
//! println!("{} faces in {}", report.faces, files.glb.display());
//! ```
//!
//! The trainer implements [`FieldSource`] for a trained model; everything
//! here is evaluated in the normalized frame and written in world units
//! through [`ExportOptions::scale_mat`].
#![deny(missing_docs)]

pub mod atlas;
pub mod bake;
mod error;
pub mod gltf;
pub mod marching;
pub mod obj;
pub mod pipeline;
pub mod render;
pub mod roundtrip;
pub mod simplify;
pub mod source;
pub mod textures;

pub use atlas::{AtlasOptions, TexturedMesh};
pub use bake::{BakeOptions, MaterialTextures};
pub use error::ExportError;
pub use gltf::{Asset, AssetFrame, read_glb, write_glb};
pub use marching::{MarchingOptions, MarchingStats, extract_surface};
pub use pipeline::{
    ExportFiles, ExportOptions, ExportReport, Exported, export_asset, export_to_dir, write_export,
};
pub use render::{
    AssetHit, AssetTracer, FlashImage, FlashSettings, LightingSettings, flash_psnr,
    render_source_flash,
};
pub use roundtrip::{
    ProjectionStats, ReferenceOptions, ViewRoundTrip, flash_round_trip, level_set_reference,
    project_to_level_set,
};
pub use source::{AnalyticSource, FieldSource, MAX_BATCH};
/// The maps [`AssetTracer::render_view`] returns (defined with the data
/// layout, in `wildlight-data`).
pub use wildlight_data::ViewMaps;
