//! `wildlight info`: describe a dataset (images, flash, cameras, masks)
//! and warn about what would spoil a reconstruction.

use std::path::PathBuf;

use anyhow::Context;
use wildlight_data::png_io::PngDecoding;
use wildlight_data::{Dataset, DatasetInfo, LoadOptions};

/// Options of `wildlight info`.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// Dataset folder (cameras_sphere.npz, image/, optional mask/ and val/).
    #[arg(long, value_name = "DIR")]
    pub data: PathBuf,
    /// Print one JSON object instead of a table.
    #[arg(long)]
    pub json: bool,
    /// Decode PNG images with the sRGB curve (phone photos) instead of value/256.
    #[arg(long)]
    pub srgb: bool,
}

/// Runs `wildlight info`.
pub fn run(args: Args) -> anyhow::Result<()> {
    let opts = LoadOptions {
        png_decoding: if args.srgb {
            PngDecoding::Srgb
        } else {
            PngDecoding::Linear256
        },
        ..LoadOptions::default()
    };
    let data = Dataset::load(&args.data, &opts).context("cannot load the dataset")?;
    let info = DatasetInfo::from_dataset(&data);
    if args.json {
        println!("{}", serde_json::to_string_pretty(&info)?);
    } else {
        print!("{}", info.to_table());
    }
    Ok(())
}
