//! The per-view maps of a rendering — image, flash and ambient terms,
//! normal, depth, accumulated weight and material parameters — as both
//! renderers produce them: a trained run's (`wildlight-train`) and an
//! exported asset's (`wildlight_export::AssetTracer::render_view`). One
//! type, so that both are written by the same code in the same layout
//! (docs/conventions.md).

use wildlight_material::PARAM_COUNT;

/// Every map rendered for one view. Per-pixel arrays are row-major,
/// `width × height` long.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct ViewMaps {
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// Rendered linear RGB (ambient + flash).
    pub rgb: Vec<[f32; 3]>,
    /// Flash-only radiance.
    pub flash: Vec<[f32; 3]>,
    /// Ambient-only radiance (for an asset, the environment itself where
    /// nothing is hit).
    pub ambient: Vec<[f32; 3]>,
    /// Unit normal (normalized frame); zero where nothing was hit.
    pub normal: Vec<[f32; 3]>,
    /// Distance along the ray to the surface (normalized frame): the
    /// weight-averaged one for a run, the hit distance for an asset; zero
    /// where nothing was hit.
    pub depth: Vec<f32>,
    /// Accumulated weight Σw (the soft mask) of a run; 1 where the ray hit
    /// and 0 elsewhere for an asset.
    pub acc: Vec<f32>,
    /// The material parameters (weight-averaged for a run); zero where
    /// nothing was hit.
    pub params: Vec<[f32; PARAM_COUNT]>,
}

impl ViewMaps {
    /// Empty maps of a `width × height` view, with room for every pixel.
    pub fn with_capacity(width: u32, height: u32) -> Self {
        let n = width as usize * height as usize;
        ViewMaps {
            width,
            height,
            rgb: Vec::with_capacity(n),
            flash: Vec::with_capacity(n),
            ambient: Vec::with_capacity(n),
            normal: Vec::with_capacity(n),
            depth: Vec::with_capacity(n),
            acc: Vec::with_capacity(n),
            params: Vec::with_capacity(n),
        }
    }

    /// Whether each pixel shows the surface: accumulated weight above ½
    /// (for an asset rendering, exactly the pixels whose ray hit it).
    pub fn hits(&self) -> Vec<bool> {
        self.acc.iter().map(|a| *a > 0.5).collect()
    }
}
