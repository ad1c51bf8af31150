//! The material parameter set Θ (appendix eq. 1).

use wildlight_real::Real;

/// Number of material parameters (base colour counts three).
pub const PARAM_COUNT: usize = 9;
/// Index of the red base-colour channel (green and blue follow).
pub const BASE_COLOR: usize = 0;
/// Index of the roughness.
pub const ROUGHNESS: usize = 3;
/// Index of the clearcoat gloss.
pub const CLEARCOAT_GLOSS: usize = 4;
/// Index of the subsurface weight.
pub const SUBSURFACE: usize = 5;
/// Index of the metallic weight.
pub const METALLIC: usize = 6;
/// Index of the dielectric (specular) weight.
pub const DIELECTRIC: usize = 7;
/// Index of the clearcoat weight.
pub const CLEARCOAT: usize = 8;

/// Names of the 9 parameters, in vector order.
pub const PARAM_NAMES: [&str; PARAM_COUNT] = [
    "base_color_r",
    "base_color_g",
    "base_color_b",
    "roughness",
    "clearcoat_gloss",
    "subsurface",
    "metallic",
    "dielectric",
    "clearcoat",
];

/// One point's material: Θ of appendix eq. 1, every value in [0, 1].
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct Material {
    /// Linear RGB base colour.
    pub base_color: [f64; 3],
    /// Roughness r (GGX alpha = r²).
    pub roughness: f64,
    /// Clearcoat gloss g (clearcoat roughness 0.1 − 0.099 g, eq. 15).
    pub clearcoat_gloss: f64,
    /// Subsurface weight.
    pub subsurface: f64,
    /// Metallic weight.
    pub metallic: f64,
    /// Dielectric (specular) weight.
    pub dielectric: f64,
    /// Clearcoat weight.
    pub clearcoat: f64,
}

impl Default for Material {
    /// A mid-grey, fairly rough plastic.
    fn default() -> Self {
        Self {
            base_color: [0.5, 0.5, 0.5],
            roughness: 0.5,
            clearcoat_gloss: 0.0,
            subsurface: 0.0,
            metallic: 0.0,
            dielectric: 0.5,
            clearcoat: 0.0,
        }
    }
}

impl Material {
    /// The parameters as a vector in the order of [`PARAM_NAMES`].
    pub fn to_array<T: Real>(&self) -> [T; PARAM_COUNT] {
        [
            T::from_f64(self.base_color[0]),
            T::from_f64(self.base_color[1]),
            T::from_f64(self.base_color[2]),
            T::from_f64(self.roughness),
            T::from_f64(self.clearcoat_gloss),
            T::from_f64(self.subsurface),
            T::from_f64(self.metallic),
            T::from_f64(self.dielectric),
            T::from_f64(self.clearcoat),
        ]
    }

    /// Builds a material from a vector in the order of [`PARAM_NAMES`].
    pub fn from_array<T: Real>(p: &[T; PARAM_COUNT]) -> Self {
        Self {
            base_color: [p[0].to_f64(), p[1].to_f64(), p[2].to_f64()],
            roughness: p[ROUGHNESS].to_f64(),
            clearcoat_gloss: p[CLEARCOAT_GLOSS].to_f64(),
            subsurface: p[SUBSURFACE].to_f64(),
            metallic: p[METALLIC].to_f64(),
            dielectric: p[DIELECTRIC].to_f64(),
            clearcoat: p[CLEARCOAT].to_f64(),
        }
    }

    /// The first parameter outside [0, 1] (or not finite), as (name, value).
    pub fn out_of_range(&self) -> Option<(&'static str, f64)> {
        self.to_array::<f64>()
            .into_iter()
            .zip(PARAM_NAMES)
            .find(|(v, _)| !(0.0..=1.0).contains(v))
            .map(|(v, n)| (n, v))
    }
}
