//! COLMAP sparse models: reading (and writing) the text format
//! (`cameras.txt`, `images.txt`, `points3D.txt`) and the binary format
//! (`cameras.bin`, `images.bin`, `points3D.bin`), little endian, as COLMAP
//! 3.8 writes them; and the camera models' projection.
//!
//! Conventions (COLMAP): an image's pose is world → camera,
//! x_cam = R(q) x_world + t with q = (qw, qx, qy, qz); the camera centre is
//! −Rᵀt; camera axes x right, y down, z forward; pixel coordinates put the
//! centre of the top-left pixel at (0.5, 0.5) (SPEC §5 puts it at (0, 0)).

use std::collections::BTreeMap;
use std::io::Write;
use std::path::{Path, PathBuf};

use glam::{DMat3, DQuat, DVec2, DVec3};

use crate::error::ImportError;

/// COLMAP's camera models (ids as in `cameras.bin`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
pub enum CameraModel {
    /// f, cx, cy.
    SimplePinhole,
    /// fx, fy, cx, cy.
    Pinhole,
    /// f, cx, cy, k.
    SimpleRadial,
    /// f, cx, cy, k1, k2.
    Radial,
    /// fx, fy, cx, cy, k1, k2, p1, p2.
    OpenCv,
    /// fx, fy, cx, cy, k1, k2, k3, k4.
    OpenCvFisheye,
    /// fx, fy, cx, cy, k1, k2, p1, p2, k3, k4, k5, k6.
    FullOpenCv,
    /// fx, fy, cx, cy, omega.
    Fov,
    /// f, cx, cy, k.
    SimpleRadialFisheye,
    /// f, cx, cy, k1, k2.
    RadialFisheye,
    /// fx, fy, cx, cy, k1, k2, p1, p2, k3, k4, sx1, sy1.
    ThinPrismFisheye,
}

const MODELS: [(CameraModel, &str, usize); 11] = [
    (CameraModel::SimplePinhole, "SIMPLE_PINHOLE", 3),
    (CameraModel::Pinhole, "PINHOLE", 4),
    (CameraModel::SimpleRadial, "SIMPLE_RADIAL", 4),
    (CameraModel::Radial, "RADIAL", 5),
    (CameraModel::OpenCv, "OPENCV", 8),
    (CameraModel::OpenCvFisheye, "OPENCV_FISHEYE", 8),
    (CameraModel::FullOpenCv, "FULL_OPENCV", 12),
    (CameraModel::Fov, "FOV", 5),
    (CameraModel::SimpleRadialFisheye, "SIMPLE_RADIAL_FISHEYE", 4),
    (CameraModel::RadialFisheye, "RADIAL_FISHEYE", 5),
    (CameraModel::ThinPrismFisheye, "THIN_PRISM_FISHEYE", 12),
];

impl CameraModel {
    /// The model with COLMAP id `id`.
    pub fn from_id(id: i32) -> Option<CameraModel> {
        usize::try_from(id)
            .ok()
            .and_then(|i| MODELS.get(i))
            .map(|m| m.0)
    }

    /// COLMAP's id.
    pub fn id(self) -> i32 {
        MODELS.iter().position(|m| m.0 == self).unwrap_or(0) as i32
    }

    /// The model named `name` (`PINHOLE`, ...).
    pub fn from_name(name: &str) -> Option<CameraModel> {
        MODELS.iter().find(|m| m.1 == name).map(|m| m.0)
    }

    /// COLMAP's name.
    pub fn name(self) -> &'static str {
        MODELS.iter().find(|m| m.0 == self).map_or("?", |m| m.1)
    }

    /// The number of parameters.
    pub fn param_count(self) -> usize {
        MODELS.iter().find(|m| m.0 == self).map_or(0, |m| m.2)
    }

    /// Whether the import can project with it (the pinhole and the
    /// perspective models with radial/tangential distortion).
    pub fn is_supported(self) -> bool {
        matches!(
            self,
            CameraModel::SimplePinhole
                | CameraModel::Pinhole
                | CameraModel::SimpleRadial
                | CameraModel::Radial
                | CameraModel::OpenCv
                | CameraModel::FullOpenCv
        )
    }
}

/// One camera of a model.
#[derive(Clone, Debug, PartialEq)]
pub struct ColmapCamera {
    /// CAMERA_ID.
    pub id: u32,
    /// The model.
    pub model: CameraModel,
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// The model's parameters.
    pub params: Vec<f64>,
}

impl ColmapCamera {
    /// Whether the model has one focal length (`f, cx, cy, ...`) rather
    /// than two (`fx, fy, cx, cy, ...`).
    pub fn has_single_focal(&self) -> bool {
        matches!(
            self.model,
            CameraModel::SimplePinhole
                | CameraModel::SimpleRadial
                | CameraModel::Radial
                | CameraModel::SimpleRadialFisheye
                | CameraModel::RadialFisheye
        )
    }

    /// Focal lengths (fx, fy).
    pub fn focal(&self) -> (f64, f64) {
        if self.has_single_focal() {
            (self.params[0], self.params[0])
        } else {
            (self.params[0], self.params[1])
        }
    }

    /// Principal point (cx, cy) in COLMAP pixel coordinates.
    pub fn principal_point(&self) -> (f64, f64) {
        if self.has_single_focal() {
            (self.params[1], self.params[2])
        } else {
            (self.params[2], self.params[3])
        }
    }

    /// Whether the model has no distortion.
    pub fn is_pinhole(&self) -> bool {
        matches!(
            self.model,
            CameraModel::SimplePinhole | CameraModel::Pinhole
        )
    }

    /// Applies the distortion to normalized image coordinates (x/z, y/z);
    /// `None` for unsupported models.
    pub fn distort(&self, uv: DVec2) -> Option<DVec2> {
        let p = &self.params;
        let (u, v) = (uv.x, uv.y);
        let (u2, v2, uv_, r2) = (u * u, v * v, u * v, u * u + v * v);
        let d = match self.model {
            CameraModel::SimplePinhole | CameraModel::Pinhole => DVec2::ZERO,
            CameraModel::SimpleRadial => uv * (p[3] * r2),
            CameraModel::Radial => uv * (p[3] * r2 + p[4] * r2 * r2),
            CameraModel::OpenCv => {
                let (k1, k2, p1, p2) = (p[4], p[5], p[6], p[7]);
                let radial = k1 * r2 + k2 * r2 * r2;
                DVec2::new(
                    u * radial + 2.0 * p1 * uv_ + p2 * (r2 + 2.0 * u2),
                    v * radial + 2.0 * p2 * uv_ + p1 * (r2 + 2.0 * v2),
                )
            }
            CameraModel::FullOpenCv => {
                let (k1, k2, p1, p2, k3, k4, k5, k6) =
                    (p[4], p[5], p[6], p[7], p[8], p[9], p[10], p[11]);
                let r4 = r2 * r2;
                let r6 = r4 * r2;
                let radial =
                    (1.0 + k1 * r2 + k2 * r4 + k3 * r6) / (1.0 + k4 * r2 + k5 * r4 + k6 * r6);
                DVec2::new(
                    u * radial + 2.0 * p1 * uv_ + p2 * (r2 + 2.0 * u2) - u,
                    v * radial + 2.0 * p2 * uv_ + p1 * (r2 + 2.0 * v2) - v,
                )
            }
            _ => return None,
        };
        Some(uv + d)
    }

    /// The pixel (COLMAP coordinates) of a point in camera coordinates;
    /// `None` behind the camera or for unsupported models.
    pub fn project(&self, p_cam: DVec3) -> Option<DVec2> {
        if p_cam.z <= 0.0 {
            return None;
        }
        let d = self.distort(DVec2::new(p_cam.x / p_cam.z, p_cam.y / p_cam.z))?;
        let (fx, fy) = self.focal();
        let (cx, cy) = self.principal_point();
        Some(DVec2::new(fx * d.x + cx, fy * d.y + cy))
    }

    /// Normalized coordinates (x/z, y/z) of a pixel (COLMAP coordinates),
    /// undoing the distortion by fixed-point iteration; `None` for
    /// unsupported models or when the iteration does not converge.
    pub fn unproject(&self, pixel: DVec2) -> Option<DVec2> {
        let (fx, fy) = self.focal();
        let (cx, cy) = self.principal_point();
        let target = DVec2::new((pixel.x - cx) / fx, (pixel.y - cy) / fy);
        let mut uv = target;
        for _ in 0..100 {
            let d = self.distort(uv)?;
            let step = target - d;
            uv += step;
            if step.length() < 1e-12 {
                return uv.is_finite().then_some(uv);
            }
        }
        let err = (self.distort(uv)? - target).length();
        (err < 1e-6 && uv.is_finite()).then_some(uv)
    }
}

/// One registered image of a model.
#[derive(Clone, Debug, PartialEq)]
pub struct ColmapImage {
    /// IMAGE_ID.
    pub id: u32,
    /// World → camera rotation as a quaternion (w, x, y, z).
    pub qvec: [f64; 4],
    /// World → camera translation.
    pub tvec: [f64; 3],
    /// CAMERA_ID.
    pub camera_id: u32,
    /// The image's name (its path relative to COLMAP's image folder).
    pub name: String,
    /// Its keypoints (x, y in COLMAP pixel coordinates) and the point each
    /// observes (−1: none).
    pub points2d: Vec<(f64, f64, i64)>,
}

impl ColmapImage {
    /// World → camera rotation R.
    pub fn rotation(&self) -> DMat3 {
        let [w, x, y, z] = self.qvec;
        DMat3::from_quat(DQuat::from_xyzw(x, y, z, w).normalize())
    }

    /// World → camera translation t.
    pub fn translation(&self) -> DVec3 {
        DVec3::from_array(self.tvec)
    }

    /// Camera centre in the world: −Rᵀt.
    pub fn center(&self) -> DVec3 {
        -(self.rotation().transpose() * self.translation())
    }

    /// Optical axis (camera +z) in the world.
    pub fn axis(&self) -> DVec3 {
        self.rotation().transpose() * DVec3::Z
    }

    /// A world point in camera coordinates.
    pub fn to_camera(&self, p_world: DVec3) -> DVec3 {
        self.rotation() * p_world + self.translation()
    }
}

/// One 3D point of a model.
#[derive(Clone, Debug, PartialEq)]
pub struct ColmapPoint {
    /// POINT3D_ID.
    pub id: u64,
    /// Position in the world.
    pub xyz: DVec3,
    /// Colour.
    pub rgb: [u8; 3],
    /// Mean reprojection error in pixels.
    pub error: f64,
    /// (IMAGE_ID, POINT2D_IDX) of every observation.
    pub track: Vec<(u32, u32)>,
}

/// A sparse model: cameras, registered images and 3D points.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct ColmapModel {
    /// Cameras by id.
    pub cameras: BTreeMap<u32, ColmapCamera>,
    /// Images by id.
    pub images: BTreeMap<u32, ColmapImage>,
    /// Points, in file order.
    pub points: Vec<ColmapPoint>,
}

/// Which of the two formats a model folder holds.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ModelFormat {
    /// `cameras.bin`, `images.bin`, `points3D.bin`.
    Binary,
    /// `cameras.txt`, `images.txt`, `points3D.txt`.
    Text,
}

fn model_err(path: &Path, message: impl Into<String>) -> ImportError {
    ImportError::Model {
        path: path.to_path_buf(),
        message: message.into(),
    }
}

impl ColmapModel {
    /// Reads a model folder, binary when `cameras.bin` is there, else text.
    pub fn read(dir: &Path) -> Result<ColmapModel, ImportError> {
        match Self::format_of(dir) {
            Some(ModelFormat::Binary) => Self::read_binary(dir),
            Some(ModelFormat::Text) => Self::read_text(dir),
            None => Err(model_err(
                dir,
                "not a COLMAP sparse model (no cameras.bin or cameras.txt); pass the folder that \
                 holds cameras, images and points3D (for example sparse/0)",
            )),
        }
    }

    /// The format of a model folder, if it holds one.
    pub fn format_of(dir: &Path) -> Option<ModelFormat> {
        if dir.join("cameras.bin").is_file() {
            Some(ModelFormat::Binary)
        } else if dir.join("cameras.txt").is_file() {
            Some(ModelFormat::Text)
        } else {
            None
        }
    }

    /// Mean reprojection error over the points (pixels); 0 without points.
    pub fn mean_reprojection_error(&self) -> f64 {
        if self.points.is_empty() {
            return 0.0;
        }
        self.points.iter().map(|p| p.error).sum::<f64>() / self.points.len() as f64
    }

    /// Checks that every image's camera exists and every track refers to
    /// an existing image and keypoint.
    fn check(self, dir: &Path) -> Result<ColmapModel, ImportError> {
        for im in self.images.values() {
            if !self.cameras.contains_key(&im.camera_id) {
                return Err(model_err(
                    dir,
                    format!(
                        "image {} ({}) uses camera {}, which the model does not have",
                        im.id, im.name, im.camera_id
                    ),
                ));
            }
        }
        Ok(self)
    }

    // ---------------------------------------------------------------- text

    /// Reads `cameras.txt`, `images.txt` and `points3D.txt`.
    pub fn read_text(dir: &Path) -> Result<ColmapModel, ImportError> {
        let read = |name: &str| -> Result<(PathBuf, String), ImportError> {
            let path = dir.join(name);
            let text =
                std::fs::read_to_string(&path).map_err(|e| ImportError::io(&path, "reading", e))?;
            Ok((path, text))
        };
        let (path, text) = read("cameras.txt")?;
        let mut cameras = BTreeMap::new();
        for (line_no, line) in text.lines().enumerate() {
            let line = line.trim();
            if line.is_empty() || line.starts_with('#') {
                continue;
            }
            let at = |m: String| model_err(&path, format!("line {}: {m}", line_no + 1));
            let f: Vec<&str> = line.split_whitespace().collect();
            if f.len() < 4 {
                return Err(at(format!(
                    "expected CAMERA_ID MODEL WIDTH HEIGHT PARAMS, found `{line}`"
                )));
            }
            let model = CameraModel::from_name(f[1])
                .ok_or_else(|| at(format!("unknown camera model {}", f[1])))?;
            let params = f[4..]
                .iter()
                .map(|v| v.parse::<f64>())
                .collect::<Result<Vec<_>, _>>()
                .map_err(|e| at(format!("bad parameter: {e}")))?;
            if params.len() != model.param_count() {
                return Err(at(format!(
                    "{} takes {} parameters, found {}",
                    f[1],
                    model.param_count(),
                    params.len()
                )));
            }
            let id: u32 = f[0]
                .parse()
                .map_err(|e| at(format!("bad CAMERA_ID: {e}")))?;
            let width = f[2].parse().map_err(|e| at(format!("bad WIDTH: {e}")))?;
            let height = f[3].parse().map_err(|e| at(format!("bad HEIGHT: {e}")))?;
            cameras.insert(
                id,
                ColmapCamera {
                    id,
                    model,
                    width,
                    height,
                    params,
                },
            );
        }

        let (path, text) = read("images.txt")?;
        let mut images = BTreeMap::new();
        // Two lines per image; the second (keypoints) may be empty, so
        // only comments are skipped.
        let mut lines = text
            .lines()
            .enumerate()
            .filter(|(_, l)| !l.trim_start().starts_with('#'));
        while let Some((line_no, line)) = lines.next() {
            if line.trim().is_empty() {
                continue;
            }
            let at = |m: String| model_err(&path, format!("line {}: {m}", line_no + 1));
            let f: Vec<&str> = line.split_whitespace().collect();
            if f.len() < 10 {
                return Err(at(format!(
                    "expected IMAGE_ID QW QX QY QZ TX TY TZ CAMERA_ID NAME, found `{line}`"
                )));
            }
            let num = |s: &str| {
                s.parse::<f64>()
                    .map_err(|e| at(format!("bad number {s}: {e}")))
            };
            let id: u32 = f[0].parse().map_err(|e| at(format!("bad IMAGE_ID: {e}")))?;
            let qvec = [num(f[1])?, num(f[2])?, num(f[3])?, num(f[4])?];
            let tvec = [num(f[5])?, num(f[6])?, num(f[7])?];
            let camera_id = f[8]
                .parse()
                .map_err(|e| at(format!("bad CAMERA_ID: {e}")))?;
            let name = f[9..].join(" ");
            let mut points2d = Vec::new();
            if let Some((pl_no, pl)) = lines.next() {
                let p: Vec<&str> = pl.split_whitespace().collect();
                if !p.len().is_multiple_of(3) {
                    return Err(model_err(
                        &path,
                        format!(
                            "line {}: keypoints of image {id} are not (X, Y, POINT3D_ID) triples",
                            pl_no + 1
                        ),
                    ));
                }
                for t in p.chunks_exact(3) {
                    let bad = |e: String| {
                        model_err(&path, format!("line {}: bad keypoint: {e}", pl_no + 1))
                    };
                    points2d.push((
                        t[0].parse().map_err(|e| bad(format!("{e}")))?,
                        t[1].parse().map_err(|e| bad(format!("{e}")))?,
                        t[2].parse().map_err(|e| bad(format!("{e}")))?,
                    ));
                }
            }
            images.insert(
                id,
                ColmapImage {
                    id,
                    qvec,
                    tvec,
                    camera_id,
                    name,
                    points2d,
                },
            );
        }

        let path = dir.join("points3D.txt");
        let mut points = Vec::new();
        if path.is_file() {
            let text =
                std::fs::read_to_string(&path).map_err(|e| ImportError::io(&path, "reading", e))?;
            for (line_no, line) in text.lines().enumerate() {
                let line = line.trim();
                if line.is_empty() || line.starts_with('#') {
                    continue;
                }
                let at = |m: String| model_err(&path, format!("line {}: {m}", line_no + 1));
                let f: Vec<&str> = line.split_whitespace().collect();
                if f.len() < 8 || !(f.len() - 8).is_multiple_of(2) {
                    return Err(at(format!(
                        "expected POINT3D_ID X Y Z R G B ERROR TRACK[], found `{line}`"
                    )));
                }
                let num = |s: &str| {
                    s.parse::<f64>()
                        .map_err(|e| at(format!("bad number {s}: {e}")))
                };
                let byte = |s: &str| {
                    s.parse::<u8>()
                        .map_err(|e| at(format!("bad colour {s}: {e}")))
                };
                let track = f[8..]
                    .chunks_exact(2)
                    .map(|t| Ok((t[0].parse()?, t[1].parse()?)))
                    .collect::<Result<Vec<(u32, u32)>, std::num::ParseIntError>>()
                    .map_err(|e| at(format!("bad track: {e}")))?;
                points.push(ColmapPoint {
                    id: f[0]
                        .parse()
                        .map_err(|e| at(format!("bad POINT3D_ID: {e}")))?,
                    xyz: DVec3::new(num(f[1])?, num(f[2])?, num(f[3])?),
                    rgb: [byte(f[4])?, byte(f[5])?, byte(f[6])?],
                    error: num(f[7])?,
                    track,
                });
            }
        }
        ColmapModel {
            cameras,
            images,
            points,
        }
        .check(dir)
    }

    /// Writes the model as `cameras.txt`, `images.txt`, `points3D.txt`.
    pub fn write_text(&self, dir: &Path) -> Result<(), ImportError> {
        std::fs::create_dir_all(dir).map_err(|e| ImportError::io(dir, "creating", e))?;
        let mut cams = String::from(
            "# Camera list with one line of data per camera:\n#   CAMERA_ID, MODEL, WIDTH, HEIGHT, PARAMS[]\n",
        );
        for c in self.cameras.values() {
            let params: Vec<String> = c.params.iter().map(|p| format!("{p:?}")).collect();
            cams += &format!(
                "{} {} {} {} {}\n",
                c.id,
                c.model.name(),
                c.width,
                c.height,
                params.join(" ")
            );
        }
        let mut ims = String::from(
            "# Image list with two lines of data per image:\n#   IMAGE_ID, QW, QX, QY, QZ, TX, TY, TZ, CAMERA_ID, NAME\n#   POINTS2D[] as (X, Y, POINT3D_ID)\n",
        );
        for im in self.images.values() {
            let [qw, qx, qy, qz] = im.qvec;
            let [tx, ty, tz] = im.tvec;
            ims += &format!(
                "{} {qw:?} {qx:?} {qy:?} {qz:?} {tx:?} {ty:?} {tz:?} {} {}\n",
                im.id, im.camera_id, im.name
            );
            let kp: Vec<String> = im
                .points2d
                .iter()
                .map(|(x, y, id)| format!("{x:?} {y:?} {id}"))
                .collect();
            ims += &kp.join(" ");
            ims += "\n";
        }
        let mut pts = String::from(
            "# 3D point list with one line of data per point:\n#   POINT3D_ID, X, Y, Z, R, G, B, ERROR, TRACK[] as (IMAGE_ID, POINT2D_IDX)\n",
        );
        for p in &self.points {
            let track: Vec<String> = p.track.iter().map(|(i, k)| format!("{i} {k}")).collect();
            pts += &format!(
                "{} {:?} {:?} {:?} {} {} {} {:?} {}\n",
                p.id,
                p.xyz.x,
                p.xyz.y,
                p.xyz.z,
                p.rgb[0],
                p.rgb[1],
                p.rgb[2],
                p.error,
                track.join(" ")
            );
        }
        for (name, text) in [
            ("cameras.txt", cams),
            ("images.txt", ims),
            ("points3D.txt", pts),
        ] {
            let path = dir.join(name);
            std::fs::write(&path, text).map_err(|e| ImportError::io(&path, "writing", e))?;
        }
        Ok(())
    }

    // -------------------------------------------------------------- binary

    /// Reads `cameras.bin`, `images.bin` and `points3D.bin`.
    pub fn read_binary(dir: &Path) -> Result<ColmapModel, ImportError> {
        let path = dir.join("cameras.bin");
        let mut r = Bytes::open(&path)?;
        let n = r.u64()?;
        let mut cameras = BTreeMap::new();
        for _ in 0..n {
            let id = r.i32()? as u32;
            let model_id = r.i32()?;
            let model = CameraModel::from_id(model_id)
                .ok_or_else(|| r.err(format!("unknown camera model id {model_id}")))?;
            let width = r.u64()? as u32;
            let height = r.u64()? as u32;
            let params = (0..model.param_count())
                .map(|_| r.f64())
                .collect::<Result<Vec<_>, _>>()?;
            cameras.insert(
                id,
                ColmapCamera {
                    id,
                    model,
                    width,
                    height,
                    params,
                },
            );
        }
        r.finish()?;

        let path = dir.join("images.bin");
        let mut r = Bytes::open(&path)?;
        let n = r.u64()?;
        let mut images = BTreeMap::new();
        for _ in 0..n {
            let id = r.i32()? as u32;
            let qvec = [r.f64()?, r.f64()?, r.f64()?, r.f64()?];
            let tvec = [r.f64()?, r.f64()?, r.f64()?];
            let camera_id = r.i32()? as u32;
            let name = r.cstr()?;
            let count = r.u64()?;
            r.need(count.saturating_mul(24))?;
            let mut points2d = Vec::with_capacity(count as usize);
            for _ in 0..count {
                points2d.push((r.f64()?, r.f64()?, r.i64()?));
            }
            images.insert(
                id,
                ColmapImage {
                    id,
                    qvec,
                    tvec,
                    camera_id,
                    name,
                    points2d,
                },
            );
        }
        r.finish()?;

        let path = dir.join("points3D.bin");
        let mut points = Vec::new();
        if path.is_file() {
            let mut r = Bytes::open(&path)?;
            let n = r.u64()?;
            for _ in 0..n {
                let id = r.u64()?;
                let xyz = DVec3::new(r.f64()?, r.f64()?, r.f64()?);
                let rgb = [r.u8()?, r.u8()?, r.u8()?];
                let error = r.f64()?;
                let len = r.u64()?;
                r.need(len.saturating_mul(8))?;
                let track = (0..len)
                    .map(|_| Ok((r.i32()? as u32, r.i32()? as u32)))
                    .collect::<Result<Vec<_>, ImportError>>()?;
                points.push(ColmapPoint {
                    id,
                    xyz,
                    rgb,
                    error,
                    track,
                });
            }
            r.finish()?;
        }
        ColmapModel {
            cameras,
            images,
            points,
        }
        .check(dir)
    }

    /// Writes the model as `cameras.bin`, `images.bin`, `points3D.bin`.
    pub fn write_binary(&self, dir: &Path) -> Result<(), ImportError> {
        std::fs::create_dir_all(dir).map_err(|e| ImportError::io(dir, "creating", e))?;
        let mut cams = Vec::new();
        cams.extend((self.cameras.len() as u64).to_le_bytes());
        for c in self.cameras.values() {
            cams.extend((c.id as i32).to_le_bytes());
            cams.extend(c.model.id().to_le_bytes());
            cams.extend((c.width as u64).to_le_bytes());
            cams.extend((c.height as u64).to_le_bytes());
            c.params.iter().for_each(|p| cams.extend(p.to_le_bytes()));
        }
        let mut ims = Vec::new();
        ims.extend((self.images.len() as u64).to_le_bytes());
        for im in self.images.values() {
            ims.extend((im.id as i32).to_le_bytes());
            im.qvec
                .iter()
                .chain(&im.tvec)
                .for_each(|v| ims.extend(v.to_le_bytes()));
            ims.extend((im.camera_id as i32).to_le_bytes());
            ims.extend(im.name.as_bytes());
            ims.push(0);
            ims.extend((im.points2d.len() as u64).to_le_bytes());
            for (x, y, id) in &im.points2d {
                ims.extend(x.to_le_bytes());
                ims.extend(y.to_le_bytes());
                ims.extend(id.to_le_bytes());
            }
        }
        let mut pts = Vec::new();
        pts.extend((self.points.len() as u64).to_le_bytes());
        for p in &self.points {
            pts.extend(p.id.to_le_bytes());
            p.xyz
                .to_array()
                .iter()
                .for_each(|v| pts.extend(v.to_le_bytes()));
            pts.extend(p.rgb);
            pts.extend(p.error.to_le_bytes());
            pts.extend((p.track.len() as u64).to_le_bytes());
            for (i, k) in &p.track {
                pts.extend((*i as i32).to_le_bytes());
                pts.extend((*k as i32).to_le_bytes());
            }
        }
        for (name, bytes) in [
            ("cameras.bin", cams),
            ("images.bin", ims),
            ("points3D.bin", pts),
        ] {
            let path = dir.join(name);
            let mut f =
                std::fs::File::create(&path).map_err(|e| ImportError::io(&path, "creating", e))?;
            f.write_all(&bytes)
                .map_err(|e| ImportError::io(&path, "writing", e))?;
        }
        Ok(())
    }
}

/// A little-endian reader over a whole file, with errors naming the file
/// and the byte offset.
struct Bytes {
    path: PathBuf,
    data: Vec<u8>,
    at: usize,
}

impl Bytes {
    fn open(path: &Path) -> Result<Bytes, ImportError> {
        let data = std::fs::read(path).map_err(|e| ImportError::io(path, "reading", e))?;
        Ok(Bytes {
            path: path.to_path_buf(),
            data,
            at: 0,
        })
    }

    fn err(&self, message: String) -> ImportError {
        model_err(&self.path, format!("byte {}: {message}", self.at))
    }

    fn need(&self, n: u64) -> Result<(), ImportError> {
        if (self.data.len() - self.at) as u64 >= n {
            Ok(())
        } else {
            Err(self.err(format!(
                "truncated: {n} more bytes needed, {} left",
                self.data.len() - self.at
            )))
        }
    }

    fn take<const N: usize>(&mut self) -> Result<[u8; N], ImportError> {
        self.need(N as u64)?;
        let b: [u8; N] = self.data[self.at..self.at + N]
            .try_into()
            .map_err(|_| self.err("internal: slice".into()))?;
        self.at += N;
        Ok(b)
    }

    fn u8(&mut self) -> Result<u8, ImportError> {
        Ok(self.take::<1>()?[0])
    }
    fn i32(&mut self) -> Result<i32, ImportError> {
        Ok(i32::from_le_bytes(self.take()?))
    }
    fn i64(&mut self) -> Result<i64, ImportError> {
        Ok(i64::from_le_bytes(self.take()?))
    }
    fn u64(&mut self) -> Result<u64, ImportError> {
        Ok(u64::from_le_bytes(self.take()?))
    }
    fn f64(&mut self) -> Result<f64, ImportError> {
        Ok(f64::from_le_bytes(self.take()?))
    }

    fn cstr(&mut self) -> Result<String, ImportError> {
        let end = self.data[self.at..]
            .iter()
            .position(|b| *b == 0)
            .ok_or_else(|| self.err("truncated: image name without its terminating zero".into()))?;
        let s = String::from_utf8_lossy(&self.data[self.at..self.at + end]).into_owned();
        self.at += end + 1;
        Ok(s)
    }

    fn finish(&self) -> Result<(), ImportError> {
        if self.at != self.data.len() {
            return Err(self.err(format!(
                "{} bytes left over after the last record",
                self.data.len() - self.at
            )));
        }
        Ok(())
    }
}
