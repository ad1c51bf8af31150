//! `wildlight brdf`: evaluates the material model of SPEC §3 on JSON lines,
//! or plots a lobe. This is how a user sees what a parameter set means, and
//! how the model is checked from outside.

use anyhow::{Context, bail};
use std::io::{BufRead, Write};
use std::path::PathBuf;
use wildlight_material::{BrdfSettings, Material, brdf};

/// Options of `wildlight brdf`.
///
/// Input: one JSON object per line, e.g.
/// `{"cos":0.7,"base_color":[0.8,0.2,0.1],"roughness":0.4,"clearcoat_gloss":0,"subsurface":0,"metallic":0,"dielectric":0.5,"clearcoat":0}`.
/// `cos` is n·h; parameters left out take the defaults of a mid-grey rough
/// plastic (base_color 0.5, roughness 0.5, dielectric 0.5, the rest 0).
/// Output: one JSON `[r,g,b]` line per input line, in the same order.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// File of JSON lines [default: standard input].
    pub file: Option<PathBuf>,
    /// Clearcoat Fresnel F_c (appendix eq. 14 uses 0.2; the public WildLight code 0.04).
    #[arg(long, value_name = "F_C", default_value_t = 0.2)]
    pub clearcoat_fresnel: f64,
    /// Instead of printing values, draw ρ (RGB) against the angle between n
    /// and h (0–90°) for every parameter set read, into this PNG. `cos` may
    /// then be left out of the input lines.
    #[arg(long, value_name = "PNG")]
    pub plot: Option<PathBuf>,
    /// With --plot: logarithmic value axis (glossy lobes span decades).
    #[arg(long, requires = "plot")]
    pub log: bool,
    /// With --plot: image width and height in pixels.
    #[arg(long, requires = "plot", default_value_t = 640, value_parser = clap::value_parser!(u32).range(160..=8192))]
    pub size: u32,
}

/// One input line.
#[derive(serde::Deserialize, Debug)]
#[serde(deny_unknown_fields)]
struct Query {
    cos: Option<f64>,
    base_color: Option<[f64; 3]>,
    roughness: Option<f64>,
    clearcoat_gloss: Option<f64>,
    subsurface: Option<f64>,
    metallic: Option<f64>,
    dielectric: Option<f64>,
    clearcoat: Option<f64>,
}

impl Query {
    fn material(&self) -> Material {
        let d = Material::default();
        Material {
            base_color: self.base_color.unwrap_or(d.base_color),
            roughness: self.roughness.unwrap_or(d.roughness),
            clearcoat_gloss: self.clearcoat_gloss.unwrap_or(d.clearcoat_gloss),
            subsurface: self.subsurface.unwrap_or(d.subsurface),
            metallic: self.metallic.unwrap_or(d.metallic),
            dielectric: self.dielectric.unwrap_or(d.dielectric),
            clearcoat: self.clearcoat.unwrap_or(d.clearcoat),
        }
    }
}

/// Parses one line; `Ok(None)` for a blank line.
fn parse_line(line: &str, need_cos: bool) -> anyhow::Result<Option<(Option<f64>, Material)>> {
    if line.trim().is_empty() {
        return Ok(None);
    }
    let q: Query = serde_json::from_str(line).context("not a valid query object")?;
    let m = q.material();
    if let Some((name, v)) = m.out_of_range() {
        bail!("{name} = {v} is outside [0, 1]");
    }
    match q.cos {
        Some(c) if !c.is_finite() || !(-1.0..=1.0).contains(&c) => {
            bail!("cos = {c} is not in [-1, 1]")
        }
        None if need_cos => bail!("missing \"cos\" (the cosine n·h)"),
        c => Ok(Some((c, m))),
    }
}

/// Runs `wildlight brdf`.
pub fn run(args: Args) -> anyhow::Result<()> {
    if !args.clearcoat_fresnel.is_finite() || !(0.0..=1.0).contains(&args.clearcoat_fresnel) {
        bail!(
            "--clearcoat-fresnel {} is outside [0, 1]",
            args.clearcoat_fresnel
        );
    }
    let settings = BrdfSettings {
        clearcoat_fresnel: args.clearcoat_fresnel,
    };
    let (source, reader): (String, Box<dyn BufRead>) = match &args.file {
        Some(p) => {
            let f =
                std::fs::File::open(p).with_context(|| format!("cannot open {}", p.display()))?;
            (
                p.display().to_string(),
                Box::new(std::io::BufReader::new(f)),
            )
        }
        None => ("<stdin>".to_string(), Box::new(std::io::stdin().lock())),
    };
    let need_cos = args.plot.is_none();
    let mut materials = Vec::new();
    let stdout = std::io::stdout();
    let mut out = std::io::BufWriter::new(stdout.lock());
    for (n, line) in reader.lines().enumerate() {
        let line = line.with_context(|| format!("{source}: cannot read line {}", n + 1))?;
        let parsed = parse_line(&line, need_cos).with_context(|| format!("{source}:{}", n + 1))?;
        let Some((cos, m)) = parsed else { continue };
        if need_cos {
            let cos = cos.expect("checked by parse_line");
            let rho = brdf::eval(&m.to_array::<f64>(), cos, &settings);
            writeln!(out, "{}", serde_json::to_string(&rho)?)?;
        } else {
            materials.push(m);
        }
    }
    out.flush()?;
    if let Some(path) = &args.plot {
        if materials.is_empty() {
            bail!("{source}: no parameter sets to plot");
        }
        lobe_plot(&materials, &settings, args.log, args.size)
            .write_png(path)
            .with_context(|| format!("cannot write the plot {}", path.display()))?;
        eprintln!(
            "wrote {} ({} parameter set{})",
            path.display(),
            materials.len(),
            if materials.len() == 1 { "" } else { "s" }
        );
    }
    Ok(())
}

/// ρ against the angle θ = acos(n·h) in degrees, one R, G, B triple of curves
/// per material (the second and later sets dashed).
fn lobe_plot(
    materials: &[Material],
    settings: &BrdfSettings,
    log: bool,
    size: u32,
) -> crate::plot::Plot {
    const COLORS: [[u8; 3]; 3] = [[220, 40, 40], [30, 160, 50], [40, 70, 220]];
    let mut series = Vec::new();
    let (mut lo, mut hi) = (f64::INFINITY, 0.0f64);
    for (k, m) in materials.iter().enumerate() {
        let p = m.to_array::<f64>();
        let mut curves = vec![Vec::new(), Vec::new(), Vec::new()];
        for i in 0..=450 {
            let theta = i as f64 * 0.2; // 0 .. 90 degrees
            let c = theta.to_radians().cos().max(1e-3);
            let rho = brdf::eval(&p, c, settings);
            for (curve, v) in curves.iter_mut().zip(rho) {
                curve.push((theta, v));
                hi = hi.max(v);
                if v > 0.0 {
                    lo = lo.min(v);
                }
            }
        }
        for (ch, points) in curves.into_iter().enumerate() {
            series.push(crate::plot::Series {
                points,
                color: COLORS[ch],
                dashed: k % 2 == 1,
            });
        }
    }
    let y_range = if log {
        let lo = if lo.is_finite() { lo } else { 1e-3 };
        (
            10f64.powf(lo.log10().floor()),
            10f64.powf(hi.max(lo * 10.0).log10().ceil()),
        )
    } else {
        (0.0, if hi > 0.0 { hi * 1.05 } else { 1.0 })
    };
    crate::plot::Plot {
        width: size,
        height: size * 3 / 4,
        x_range: (0.0, 90.0),
        y_range,
        log_y: log,
        x_tick: 15.0,
        series,
    }
}
