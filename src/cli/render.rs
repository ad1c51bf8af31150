//! `wildlight render`: renders a trained run from a capture's cameras, with
//! every map (image, flash-only, ambient-only, normal, depth, base colour,
//! roughness, metallic, all 9 parameters, accumulated weight). The output
//! folder is what `wildlight eval images` and `eval materials` read.

use anyhow::{Context, bail};
use indicatif::{ProgressBar, ProgressStyle};
use std::path::PathBuf;
use wildlight_data::Dataset;
use wildlight_train::inference::{TrainedRun, render_views_to_dir};

/// Which cameras to render.
#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum Split {
    /// The training views.
    Train,
    /// The held-out views in the capture's `val/` folder.
    Val,
}

/// Whether the flash is on in the rendering.
#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum Flash {
    /// Every view with the flash (the capture's flash energy).
    On,
    /// Every view without the flash (ambient light only).
    Off,
    /// As each photo was taken.
    AsCaptured,
}

/// Options of `wildlight render`.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// The run folder written by `wildlight train`.
    #[arg(long, value_name = "RUN")]
    pub run: PathBuf,
    /// Capture whose cameras are rendered [default: the run's own capture].
    #[arg(long, value_name = "DIR")]
    pub data: Option<PathBuf>,
    /// Which split's cameras.
    #[arg(long, value_enum, default_value_t = Split::Val)]
    pub split: Split,
    /// Views to render by image index, e.g. `0,3,5-7` [default: all].
    #[arg(long, value_name = "LIST")]
    pub views: Option<String>,
    /// Flash on, off, or as captured.
    #[arg(long, value_enum, default_value_t = Flash::AsCaptured)]
    pub flash: Flash,
    /// Output folder [default: RUN/render-<split>].
    #[arg(long, value_name = "DIR")]
    pub out: Option<PathBuf>,
    /// Resolution as a fraction of the capture's.
    #[arg(long, default_value_t = 1.0)]
    pub scale: f64,
    /// No progress bar.
    #[arg(long)]
    pub quiet: bool,
}

/// Parses `0,3,5-7` into indices.
fn parse_views(text: &str) -> anyhow::Result<Vec<usize>> {
    let mut out = Vec::new();
    for part in text.split(',').map(str::trim).filter(|p| !p.is_empty()) {
        if let Some((a, b)) = part.split_once('-') {
            let (a, b): (usize, usize) = (
                a.trim()
                    .parse()
                    .with_context(|| format!("--views: '{part}' is not a range"))?,
                b.trim()
                    .parse()
                    .with_context(|| format!("--views: '{part}' is not a range"))?,
            );
            if a > b {
                bail!("--views: range '{part}' is empty");
            }
            out.extend(a..=b);
        } else {
            out.push(
                part.parse()
                    .with_context(|| format!("--views: '{part}' is not an index"))?,
            );
        }
    }
    Ok(out)
}

/// Runs `wildlight render`.
pub fn run(args: Args) -> anyhow::Result<()> {
    if !(args.scale > 0.0 && args.scale <= 4.0) {
        bail!("--scale {} is outside (0, 4]", args.scale);
    }
    let mut trained = TrainedRun::load(&args.run)?;
    let data = args
        .data
        .clone()
        .unwrap_or_else(|| trained.info.data.clone());
    let split_dir = match args.split {
        Split::Train => data.clone(),
        Split::Val => data.join("val"),
    };
    let cameras = Dataset::load_cameras(&split_dir)
        .with_context(|| format!("cannot read the cameras of {}", split_dir.display()))?;
    // The flash energy used for --flash on: the capture's own.
    let train_cameras = if args.split == Split::Train {
        cameras.clone()
    } else {
        Dataset::load_cameras(&data).unwrap_or_default()
    };
    let capture_energy = train_cameras
        .iter()
        .chain(&cameras)
        .find(|c| c.flash())
        .map(|c| c.light_energy.map(|e| e as f32));
    let wanted = match &args.views {
        Some(list) => {
            let idx = parse_views(list)?;
            for i in &idx {
                if !cameras.iter().any(|c| c.index == *i) {
                    bail!("--views: {} has no view {i}", split_dir.display());
                }
            }
            idx
        }
        None => cameras.iter().map(|c| c.index).collect(),
    };
    let split_name = match args.split {
        Split::Train => "train",
        Split::Val => "val",
    };
    let out = args
        .out
        .clone()
        .unwrap_or_else(|| args.run.join(format!("render-{split_name}")));
    let bar = if args.quiet || !std::io::IsTerminal::is_terminal(&std::io::stderr()) {
        ProgressBar::hidden()
    } else {
        ProgressBar::new(wanted.len() as u64).with_style(
            ProgressStyle::with_template("rendering [{bar:30}] {pos}/{len} views ETA {eta}")
                .expect("valid template")
                .progress_chars("=> "),
        )
    };
    let chosen: Vec<&wildlight_data::Camera> = wanted
        .iter()
        .map(|i| {
            cameras
                .iter()
                .find(|c| c.index == *i)
                .expect("checked above")
        })
        .collect();
    if args.flash == Flash::On && capture_energy.is_none() {
        bail!("--flash on: no view of {} has the flash on", data.display());
    }
    let flash = args.flash;
    let records = render_views_to_dir(
        &mut trained,
        &chosen,
        |camera| match flash {
            Flash::Off => [0.0; 3],
            Flash::AsCaptured => camera.light_energy.map(|e| e as f32),
            Flash::On => capture_energy.unwrap_or([0.0; 3]),
        },
        split_name,
        args.scale,
        &out,
        || bar.inc(1),
    )?;
    bar.finish_and_clear();
    eprintln!("rendered {} views into {}", records.len(), out.display());
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::parse_views;

    #[test]
    fn view_lists() {
        assert_eq!(parse_views("0,3,5-7").unwrap(), vec![0, 3, 5, 6, 7]);
        assert!(parse_views("4-2").is_err());
        assert!(parse_views("x").is_err());
    }
}
