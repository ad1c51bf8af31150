//! The ground-truth material of a synthetic capture (`gt/material.json`):
//! what it is made of, and the frame in which it is defined, so that the
//! material can be evaluated at any surface point after the fact.
//!
//! ```no_run
//! use wildlight_synth::GroundTruthMaterial;
//! let gt = GroundTruthMaterial::load(std::path::Path::new("capture/gt/material.json")).unwrap();
//! let m = gt.eval_normalized(glam::DVec3::new(0.1, 0.2, 0.3));
//! println!("roughness {}", m.roughness);
//! ```

use std::path::Path;

use glam::DVec3;
use serde::{Deserialize, Serialize};
use wildlight_material::{BrdfSettings, Material};

use crate::error::SynthError;
use crate::scenes::{PROCEDURAL_MATERIALS, procedural_material};

/// Format tag written in `gt/material.json`.
pub const MATERIAL_FORMAT: &str = "wildlight-synth-material";

/// How the material varies over the object.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum MaterialDefinition {
    /// A built-in procedural material (one of `PROCEDURAL_MATERIALS`),
    /// a function of the normalized-frame position.
    Procedural {
        /// Its name.
        name: String,
    },
    /// The same material everywhere.
    Constant {
        /// The material.
        material: Material,
    },
}

impl MaterialDefinition {
    /// Parses the `--material` option: the name of a procedural material
    /// or a JSON object of `wildlight_material::Material` fields (missing
    /// fields take the defaults), e.g. `{"base_color":[0.8,0.1,0.1],"roughness":0.3}`.
    pub fn parse(text: &str) -> Result<MaterialDefinition, SynthError> {
        let err = |problem: String| SynthError::Material {
            source_name: "--material".into(),
            problem,
        };
        let t = text.trim();
        if t.starts_with('{') {
            let material: Material = serde_json::from_str(t).map_err(|e| err(e.to_string()))?;
            let def = MaterialDefinition::Constant { material };
            def.validate().map_err(err)?;
            Ok(def)
        } else if PROCEDURAL_MATERIALS.contains(&t) {
            Ok(MaterialDefinition::Procedural {
                name: t.to_string(),
            })
        } else {
            Err(err(format!(
                "'{t}' is neither a JSON object nor a procedural material ({})",
                PROCEDURAL_MATERIALS.join(", ")
            )))
        }
    }

    /// Checks names and parameter ranges.
    pub fn validate(&self) -> Result<(), String> {
        match self {
            MaterialDefinition::Procedural { name } => {
                if PROCEDURAL_MATERIALS.contains(&name.as_str()) {
                    Ok(())
                } else {
                    Err(format!(
                        "unknown procedural material '{name}' (known: {})",
                        PROCEDURAL_MATERIALS.join(", ")
                    ))
                }
            }
            MaterialDefinition::Constant { material } => match material.out_of_range() {
                Some((name, v)) => Err(format!("{name} = {v} is outside [0, 1]")),
                None => Ok(()),
            },
        }
    }

    /// The material at `p` (normalized frame).
    pub fn eval(&self, p: DVec3) -> Material {
        match self {
            MaterialDefinition::Procedural { name } => {
                procedural_material(name, p).unwrap_or_default()
            }
            MaterialDefinition::Constant { material } => *material,
        }
    }
}

/// The content of `gt/material.json`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct GroundTruthMaterial {
    /// Always [`MATERIAL_FORMAT`].
    pub format: String,
    /// Format version (1).
    pub version: u32,
    /// The built-in scene's name, or the mesh file given with `--mesh`.
    pub scene: String,
    /// The material as a function of the normalized-frame position.
    pub material: MaterialDefinition,
    /// x_world = world_scale · x_normalized + world_offset (the capture's scale_mat).
    pub world_scale: f64,
    /// See `world_scale`.
    pub world_offset: [f64; 3],
    /// Settings of the material model the images were rendered with.
    pub brdf_settings: BrdfSettings,
}

impl GroundTruthMaterial {
    /// The ground truth for `material` on `scene` in a capture whose
    /// normalized frame maps to the world by `world_scale`, `world_offset`.
    pub fn new(
        scene: &str,
        material: MaterialDefinition,
        world_scale: f64,
        world_offset: [f64; 3],
        brdf_settings: BrdfSettings,
    ) -> Self {
        GroundTruthMaterial {
            format: MATERIAL_FORMAT.into(),
            version: 1,
            scene: scene.into(),
            material,
            world_scale,
            world_offset,
            brdf_settings,
        }
    }

    /// Reads and checks `gt/material.json`.
    pub fn load(path: &Path) -> Result<GroundTruthMaterial, SynthError> {
        let text = std::fs::read_to_string(path).map_err(|e| SynthError::Io {
            path: path.to_path_buf(),
            action: "reading",
            source: e,
        })?;
        let err = |problem: String| SynthError::Material {
            source_name: path.display().to_string(),
            problem,
        };
        let gt: GroundTruthMaterial =
            serde_json::from_str(&text).map_err(|e| err(e.to_string()))?;
        if gt.format != MATERIAL_FORMAT {
            return Err(err(format!(
                "format is '{}', expected '{MATERIAL_FORMAT}'",
                gt.format
            )));
        }
        if gt.version != 1 {
            return Err(err(format!(
                "version {} is not supported (expected 1)",
                gt.version
            )));
        }
        if !(gt.world_scale > 0.0 && gt.world_scale.is_finite()) {
            return Err(err(format!(
                "world_scale must be positive, found {}",
                gt.world_scale
            )));
        }
        gt.material.validate().map_err(err)?;
        Ok(gt)
    }

    /// Writes the file atomically (pretty JSON).
    pub fn save(&self, path: &Path) -> Result<(), SynthError> {
        let text = serde_json::to_string_pretty(self).map_err(|e| SynthError::Material {
            source_name: path.display().to_string(),
            problem: e.to_string(),
        })?;
        wildlight_data::atomic::write_bytes_atomically(path, text.as_bytes())?;
        Ok(())
    }

    /// Maps a world point to the normalized frame.
    pub fn to_normalized(&self, p_world: DVec3) -> DVec3 {
        (p_world - DVec3::from(self.world_offset)) / self.world_scale
    }

    /// The material at a normalized-frame point.
    pub fn eval_normalized(&self, p: DVec3) -> Material {
        self.material.eval(p)
    }

    /// The material at a world point.
    pub fn eval_world(&self, p_world: DVec3) -> Material {
        self.material.eval(self.to_normalized(p_world))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parses_names_and_json() {
        assert_eq!(
            MaterialDefinition::parse("kettle").unwrap(),
            MaterialDefinition::Procedural {
                name: "kettle".into()
            }
        );
        let c =
            MaterialDefinition::parse(r#"{"base_color":[0.8,0.1,0.1],"roughness":0.3}"#).unwrap();
        let m = c.eval(DVec3::ZERO);
        assert_eq!(m.base_color, [0.8, 0.1, 0.1]);
        assert_eq!(m.roughness, 0.3);
        assert_eq!(m.metallic, Material::default().metallic);
        let e = MaterialDefinition::parse(r#"{"roughness":1.5}"#)
            .unwrap_err()
            .to_string();
        assert!(e.contains("roughness") && e.contains("--material"), "{e}");
        let e = MaterialDefinition::parse("velvet").unwrap_err().to_string();
        assert!(e.contains("velvet") && e.contains("patches"), "{e}");
        assert!(MaterialDefinition::parse(r#"{"shininess":1}"#).is_err());
    }

    #[test]
    fn file_round_trip_and_world_mapping() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("material.json");
        let gt = GroundTruthMaterial::new(
            "kettle",
            MaterialDefinition::Procedural {
                name: "kettle".into(),
            },
            2.0,
            [1.0, -1.0, 0.5],
            BrdfSettings::default(),
        );
        gt.save(&path).unwrap();
        let back = GroundTruthMaterial::load(&path).unwrap();
        assert_eq!(back, gt);
        let p = DVec3::new(0.1, 0.35, 0.05);
        let w = p * 2.0 + DVec3::new(1.0, -1.0, 0.5);
        assert_eq!(back.eval_world(w), back.eval_normalized(p));
        std::fs::write(&path, r#"{"format":"other","version":1}"#).unwrap();
        let e = GroundTruthMaterial::load(&path).unwrap_err().to_string();
        assert!(e.contains("material.json"), "{e}");
    }
}
