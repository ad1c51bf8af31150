//! `wildlight import`: a folder of photos → a posed capture (SPEC §5)
//! with COLMAP poses, linear exposure-normalized images, flash labels and
//! an automatic region of interest. All the work is in `wildlight-import`.

use std::path::{Path, PathBuf};

use anyhow::{Context, bail};
use wildlight_import::{ImportOptions, Roi, import};

/// Options of `wildlight import`.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// Folder of photos (JPEG, PNG 8/16-bit, or linear EXR), all one size.
    #[arg(value_name = "PHOTOS_DIR")]
    pub photos: PathBuf,
    /// Capture folder to write (replaced if it holds an earlier import).
    #[arg(long, value_name = "CAPTURE")]
    pub out: PathBuf,
    #[command(flatten)]
    pub import: ImportArgs,
    /// Print the report (import.json) instead of the table; no progress lines.
    #[arg(long)]
    pub json: bool,
}

/// How photos are imported: the options `import` and `reconstruct` share.
#[derive(clap::Args, Debug, Clone)]
pub struct ImportArgs {
    /// Photos taken with the flash on: a glob or a comma-separated list of
    /// file names (overrides EXIF).
    #[arg(long, value_name = "GLOB|LIST")]
    pub flash: Option<String>,
    /// Photos taken with the flash off: a glob or a comma-separated list of
    /// file names (overrides EXIF).
    #[arg(long = "no-flash", value_name = "GLOB|LIST")]
    pub no_flash: Option<String>,
    /// Use this COLMAP sparse model (text or binary) instead of running COLMAP.
    #[arg(long, value_name = "SPARSE_DIR")]
    pub colmap: Option<PathBuf>,
    /// Centre of the region of interest, in the COLMAP model's units (with --radius).
    #[arg(long, value_name = "X,Y,Z", requires = "radius")]
    pub center: Option<String>,
    /// Radius of the region of interest, in the COLMAP model's units (with --center).
    #[arg(long, value_name = "R", requires = "center")]
    pub radius: Option<f64>,
    /// Longer side of the capture's images in pixels.
    #[arg(long, value_name = "PIXELS", default_value_t = wildlight_import::import::DEFAULT_MAX_SIZE)]
    pub max_size: u32,
}

impl ImportArgs {
    /// The import of `photos` into `out` with these options.
    pub fn options(&self, photos: &Path, out: &Path) -> anyhow::Result<ImportOptions> {
        let mut opts = ImportOptions::new(photos, out);
        opts.flash = self.flash.clone();
        opts.no_flash = self.no_flash.clone();
        opts.colmap_model = self.colmap.clone();
        opts.max_size = self.max_size;
        if let (Some(c), Some(r)) = (&self.center, self.radius) {
            opts.roi = Some(Roi {
                center: parse_center(c)?,
                radius: r,
            });
        }
        Ok(opts)
    }
}

/// Parses `X,Y,Z`.
fn parse_center(text: &str) -> anyhow::Result<glam::DVec3> {
    let v: Vec<f64> = text
        .split(',')
        .map(|s| s.trim().parse::<f64>())
        .collect::<Result<_, _>>()
        .with_context(|| format!("--center {text}: expected three numbers X,Y,Z"))?;
    match v.as_slice() {
        [x, y, z] if v.iter().all(|c| c.is_finite()) => Ok(glam::DVec3::new(*x, *y, *z)),
        _ => bail!("--center {text}: expected three numbers X,Y,Z"),
    }
}

/// Runs `wildlight import`.
pub fn run(args: Args) -> anyhow::Result<()> {
    let opts = args.import.options(&args.photos, &args.out)?;
    let quiet = args.json;
    let progress = move |line: &str| {
        if !quiet {
            eprintln!("import: {line}");
        }
    };
    let report = import(&opts, &progress)
        .with_context(|| format!("cannot import {}", args.photos.display()))?;
    if args.json {
        println!("{}", serde_json::to_string_pretty(&report)?);
    } else {
        print!("{}", report.to_table());
        println!(
            "wrote {} (cameras_sphere.npz, image/, import.json, roi.png)",
            args.out.display()
        );
    }
    Ok(())
}
