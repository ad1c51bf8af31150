//! Settings of experiments that were measured and not kept (issue 48; the
//! measurements are in `docs/benchmark-log.md`, "Settings: the measurements
//! behind the defaults"). A run folder written before they were retired
//! names them in its `config.toml`; such a file still loads: the retired
//! keys are left out with a warning that names them, and a second warning
//! names those that held anything but their old default, since the run they
//! describe used an experiment that this version no longer has.

use toml::de::{DeTable, DeValue};

/// Every retired setting with the default it had, which left its
/// experiment off.
const RETIRED_DEFAULTS: &str = r#"
error_fraction = 0.0
error_from = 0.0
error_tile = 4

[loss]
color_l2 = 0.0
color_l2_start = 0.0
smoothness_relative = "pair"
smoothness_saturation = 0.0
smoothness_saturation_start = 0.0
smoothness_saturated_parameters = ["base_color", "roughness", "clearcoat_gloss", "subsurface", "metallic", "dielectric", "clearcoat"]
smoothness_radius_start = 0.0
wide_smoothness_radius = 0.0
wide_smoothness_parameters = []
normal_smoothness_radius = 0.0
normal_smoothness_relax = 0.0
normal_difference = "second"
binary_metallic_min_resolution = 0
binary_metallic_readout_only = true
binary_metallic_anchor = 0.0
binary_metallic_ceiling = 1.0

[loss.smoothness_factors]
base_color = 1.0
roughness = 1.0
clearcoat_gloss = 1.0
subsurface = 1.0
metallic = 1.0
dielectric = 1.0
clearcoat = 1.0

[optim]
metallic_hold = 0.0

[model]
ambient_flash_gradient = 1.0
ambient_direction = "reflected"
ambient_sh_bands = 4

[model.ambient_specular]
levels = 3
features_per_level = 2
log2_table_size = 12
base_resolution = 2
finest_resolution = 8
hidden = [64]
interpolation = "linear"
"#;

/// Retired settings that had no default: absent, their experiment was off.
const RETIRED_WITHOUT_DEFAULT: [&str; 1] = ["model.metallic_field"];

/// A retired setting that a configuration named.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct RetiredSetting {
    /// Its dotted key, e.g. `loss.color_l2`.
    pub key: String,
    /// Whether it held something other than its old default (the run it
    /// describes used the retired experiment).
    pub was_on: bool,
}

/// The dotted keys of every retired setting: those of [`RETIRED_DEFAULTS`]
/// (sorted within each table), then those without a default.
pub fn retired_keys() -> Vec<String> {
    let defaults = defaults();
    let mut keys = Vec::new();
    collect_keys(&defaults, "", &mut keys);
    keys.extend(RETIRED_WITHOUT_DEFAULT.map(String::from));
    keys
}

fn defaults() -> toml::Table {
    RETIRED_DEFAULTS
        .parse()
        .expect("the retired settings' defaults are valid TOML")
}

/// The leaf keys of `table` and the keys of its retired sub-tables (a
/// sub-table whose parent is itself a setting table, such as
/// `loss.smoothness_factors`, is one retired setting).
fn collect_keys(table: &toml::Table, prefix: &str, out: &mut Vec<String>) {
    for (key, value) in table {
        let path = format!("{prefix}{key}");
        match value {
            // `loss`, `optim` and `model` hold settings; deeper tables are
            // settings themselves
            toml::Value::Table(inner) if prefix.is_empty() => {
                collect_keys(inner, &format!("{path}."), out)
            }
            _ => out.push(path),
        }
    }
}

/// Removes every retired setting from a parsed configuration and returns
/// them, in the order of [`retired_keys`].
pub fn strip(root: &mut DeTable<'_>) -> Vec<RetiredSetting> {
    let defaults = defaults();
    let mut found = Vec::new();
    for key in retired_keys() {
        let (parent, name) = match key.rsplit_once('.') {
            Some((parent, name)) => (Some(parent), name),
            None => (None, key.as_str()),
        };
        let table = match parent {
            None => Some(&mut *root),
            Some(parent) => match root.get_mut(parent).map(|v| v.get_mut()) {
                Some(DeValue::Table(t)) => Some(t),
                _ => None,
            },
        };
        let Some(value) = table.and_then(|t| t.remove(name)) else {
            continue;
        };
        let default = parent
            .and_then(|p| defaults.get(p))
            .and_then(|t| t.get(name))
            .or_else(|| defaults.get(&key));
        let was_on = default.is_none_or(|d| !holds(value.get_ref(), d));
        found.push(RetiredSetting { key, was_on });
    }
    found
}

/// Whether a parsed value holds `default` (numbers compared as numbers, a
/// table by the keys it gives).
fn holds(value: &DeValue<'_>, default: &toml::Value) -> bool {
    use toml::Value as V;
    match (value, default) {
        (DeValue::Integer(_) | DeValue::Float(_), V::Integer(_) | V::Float(_)) => {
            let d = default
                .as_float()
                .or(default.as_integer().map(|i| i as f64));
            number(value).is_some_and(|v| Some(v) == d)
        }
        (DeValue::String(s), V::String(d)) => s == d,
        (DeValue::Boolean(b), V::Boolean(d)) => b == d,
        (DeValue::Array(a), V::Array(d)) => {
            a.len() == d.len() && a.iter().zip(d).all(|(a, d)| holds(a.get_ref(), d))
        }
        (DeValue::Table(t), V::Table(d)) => t.iter().all(|(k, v)| {
            d.get(k.get_ref().as_ref())
                .is_some_and(|d| holds(v.get_ref(), d))
        }),
        _ => false,
    }
}

/// A parsed number as f64.
fn number(value: &DeValue<'_>) -> Option<f64> {
    match value {
        DeValue::Integer(i) => i64::from_str_radix(i.as_str(), i.radix())
            .ok()
            .map(|i| i as f64),
        DeValue::Float(f) => f.as_str().parse().ok(),
        _ => None,
    }
}

/// The warnings a configuration with `retired` settings gets (none without).
pub fn warnings(retired: &[RetiredSetting]) -> Vec<String> {
    let names = |on: bool| -> Vec<&str> {
        retired
            .iter()
            .filter(|r| !on || r.was_on)
            .map(|r| r.key.as_str())
            .collect()
    };
    let mut out = Vec::new();
    if !retired.is_empty() {
        out.push(format!(
            "retired settings ignored: {}",
            names(false).join(", ")
        ));
    }
    let on = names(true);
    if !on.is_empty() {
        out.push(format!(
            "{} turned on retired experiments; this version trains and renders without them",
            on.join(", ")
        ));
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::config::TrainConfig;

    #[test]
    fn every_retired_setting_is_listed_once() {
        let keys = retired_keys();
        assert_eq!(keys.len(), 26, "{keys:?}");
        for key in [
            "error_fraction",
            "loss.color_l2",
            "loss.smoothness_factors",
            "optim.metallic_hold",
            "model.ambient_specular",
            "model.metallic_field",
        ] {
            assert_eq!(keys.iter().filter(|k| *k == key).count(), 1, "{key}");
        }
        // none of them is a setting any more
        let printed = TrainConfig::default().to_toml();
        let table: toml::Table = printed.parse().unwrap();
        for key in &keys {
            let (parent, name) = key.rsplit_once('.').unwrap_or(("", key));
            let t = if parent.is_empty() {
                Some(&table)
            } else {
                table.get(parent).and_then(|v| v.as_table())
            };
            assert!(t.is_none_or(|t| !t.contains_key(name)), "{key}");
        }
    }

    /// The whole default configuration as the trainer printed it before
    /// the settings were retired (`--iters 150`) loads as today's defaults
    /// with every retired key named and none of them on.
    #[test]
    fn the_default_configuration_of_before_loads() {
        let old = include_str!("../tests/data/config-before-issue-48.toml");
        let (config, retired) = TrainConfig::from_toml_with_retired(old).unwrap();
        assert_eq!(
            config,
            TrainConfig {
                iters: 150,
                ..TrainConfig::default()
            }
        );
        let mut all = retired_keys();
        all.retain(|k| k != "model.metallic_field");
        let named: Vec<String> = retired.iter().map(|r| r.key.clone()).collect();
        assert_eq!(named, all);
        assert!(retired.iter().all(|r| !r.was_on), "{retired:?}");
        assert_eq!(warnings(&retired).len(), 1);
    }

    /// A configuration written before the settings were retired loads, its
    /// retired keys named; those that held their old defaults are not
    /// flagged as experiments.
    #[test]
    fn an_old_configuration_loads_with_its_retired_keys_named() {
        let mut old = TrainConfig::default().to_toml();
        old = old.replace(
            "[loss]\n",
            "error_tile = 4\n\n[loss]\ncolor_l2 = 0.0\nnormal_difference = \"second\"\n",
        );
        old.push_str("\n[loss.smoothness_factors]\nbase_color = 1\nroughness = 1.0\n");
        old.push_str("\n[model.ambient_specular]\nlevels = 3\nhidden = [64]\n");
        let (config, retired) = TrainConfig::from_toml_with_retired(&old).unwrap();
        assert_eq!(config, TrainConfig::default());
        let keys: Vec<&str> = retired.iter().map(|r| r.key.as_str()).collect();
        assert_eq!(
            keys,
            [
                "error_tile",
                "loss.color_l2",
                "loss.normal_difference",
                "loss.smoothness_factors",
                "model.ambient_specular"
            ]
        );
        assert!(retired.iter().all(|r| !r.was_on), "{retired:?}");
        let w = warnings(&retired);
        assert_eq!(w.len(), 1, "{w:?}");
        assert!(
            w[0].starts_with("retired settings ignored: error_tile, loss.color_l2,"),
            "{w:?}"
        );
        // nothing retired, no warning
        let (_, none) = TrainConfig::from_toml_with_retired("iters = 5\n").unwrap();
        assert!(none.is_empty() && warnings(&none).is_empty());
    }

    /// A retired key that held something else than its old default is
    /// named as an experiment that this version no longer runs.
    #[test]
    fn a_retired_experiment_that_was_on_is_named() {
        let text = "[loss]\ncolor_l2 = 10\nsmoothness_relative = \"batch\"\nbinary_metallic_ceiling = 1\n\
                    [loss.smoothness_factors]\nmetallic = 3\n\
                    [model.metallic_field]\nlevels = 2\n";
        let (config, retired) = TrainConfig::from_toml_with_retired(text).unwrap();
        assert_eq!(config, TrainConfig::default());
        let on: Vec<&str> = retired
            .iter()
            .filter(|r| r.was_on)
            .map(|r| r.key.as_str())
            .collect();
        assert_eq!(
            on,
            [
                "loss.color_l2",
                "loss.smoothness_factors",
                "loss.smoothness_relative",
                "model.metallic_field"
            ]
        );
        let w = warnings(&retired);
        assert_eq!(w.len(), 2, "{w:?}");
        assert!(
            w[1].starts_with("loss.color_l2, loss.smoothness_factors, loss.smoothness_relative,"),
            "{w:?}"
        );
        assert!(!w[1].contains("binary_metallic_ceiling"), "{w:?}");
    }

    /// A key that never was a setting is still refused, by name and line,
    /// in a file that also holds retired ones.
    #[test]
    fn a_misspelt_key_beside_retired_ones_is_refused() {
        let text = "[loss]\ncolor_l2 = 0.0\nnormal_smoothnes = 2.0\n";
        let err = TrainConfig::from_toml_with_retired(text)
            .unwrap_err()
            .to_string();
        assert!(err.contains("normal_smoothnes"), "{err}");
        assert!(err.contains("line 3"), "{err}");
        // a retired name in the wrong table is not a retired setting
        let err = TrainConfig::from_toml("[optim]\ncolor_l2 = 0.0\n")
            .unwrap_err()
            .to_string();
        assert!(err.contains("color_l2"), "{err}");
    }
}
