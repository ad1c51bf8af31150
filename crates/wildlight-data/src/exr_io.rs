//! OpenEXR reading and writing (linear float images).
//!
//! Channels are looked up by NAME, never by position: Mitsuba, like most
//! writers, stores them sorted (B, G, R). Any sample type (f16, f32, u32)
//! is converted to f32.

use std::path::Path;

use exr::prelude::{
    AnyChannel, AnyChannels, Encoding, FlatSamples, Image, Layer, LayerAttributes, ReadChannels,
    ReadLayers, WritableImage,
};

use crate::atomic::write_atomically;
use crate::error::DataError;
use crate::image::RgbImage;

/// All channels of the first layer of an EXR file.
#[derive(Clone, Debug, PartialEq)]
pub struct ExrChannels {
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// `(name, values)` with `width · height` row-major values each, in file order.
    pub channels: Vec<(String, Vec<f32>)>,
}

impl ExrChannels {
    /// The values of the channel called `name` (exact match, or a layered
    /// name ending in `.name`).
    pub fn channel(&self, name: &str) -> Option<&[f32]> {
        let suffix = format!(".{name}");
        self.channels
            .iter()
            .find(|(n, _)| n == name)
            .or_else(|| self.channels.iter().find(|(n, _)| n.ends_with(&suffix)))
            .map(|(_, v)| v.as_slice())
    }

    /// The channel names, comma separated (for messages).
    pub fn names(&self) -> String {
        self.channels
            .iter()
            .map(|(n, _)| n.as_str())
            .collect::<Vec<_>>()
            .join(", ")
    }
}

fn bad_exr(path: &Path, err: impl std::fmt::Display) -> DataError {
    DataError::BadImage {
        path: path.to_path_buf(),
        format: "EXR",
        message: err.to_string(),
    }
}

fn check_exists(path: &Path) -> Result<(), DataError> {
    if !path.is_file() {
        return Err(DataError::MissingFile {
            path: path.to_path_buf(),
            what: "EXR image".into(),
        });
    }
    Ok(())
}

/// Reads every channel of the first valid layer of `path` (largest resolution level, flat data).
pub fn read_exr_channels(path: &Path) -> Result<ExrChannels, DataError> {
    check_exists(path)?;
    let image = exr::prelude::read()
        .no_deep_data()
        .largest_resolution_level()
        .all_channels()
        .first_valid_layer()
        .all_attributes()
        .from_file(path)
        .map_err(|e| bad_exr(path, e))?;
    let layer = image.layer_data;
    let (width, height) = (layer.size.width(), layer.size.height());
    let channels = layer
        .channel_data
        .list
        .iter()
        .map(|c| {
            (
                c.name.to_string(),
                c.sample_data.values_as_f32().collect::<Vec<f32>>(),
            )
        })
        .collect::<Vec<_>>();
    let n = width * height;
    if let Some((name, v)) = channels.iter().find(|(_, v)| v.len() != n) {
        return Err(bad_exr(
            path,
            format!(
                "channel {name} has {} samples, expected {n} (subsampled channels are not supported)",
                v.len()
            ),
        ));
    }
    Ok(ExrChannels {
        width: width as u32,
        height: height as u32,
        channels,
    })
}

/// Reads a linear RGB image from the channels named R, G, B (a single Y
/// channel is read as grey). Fails when the file is unreadable or has no
/// such channels; NaN/inf values are NOT checked here (see
/// [`RgbImage::check_finite`]).
pub fn read_exr_rgb(path: &Path) -> Result<RgbImage, DataError> {
    let ex = read_exr_channels(path)?;
    let n = ex.width as usize * ex.height as usize;
    let mut data = vec![0.0f32; 3 * n];
    match (
        ex.channel("R"),
        ex.channel("G"),
        ex.channel("B"),
        ex.channel("Y"),
    ) {
        (Some(r), Some(g), Some(b), _) => {
            for i in 0..n {
                data[3 * i] = r[i];
                data[3 * i + 1] = g[i];
                data[3 * i + 2] = b[i];
            }
        }
        (None, None, None, Some(y)) => {
            for i in 0..n {
                data[3 * i..3 * i + 3].fill(y[i]);
            }
        }
        _ => {
            return Err(bad_exr(
                path,
                format!("no R, G, B channels (channels present: {})", ex.names()),
            ));
        }
    }
    Ok(RgbImage {
        width: ex.width,
        height: ex.height,
        data,
    })
}

/// The size (width, height) of the first layer, read from the header only.
pub fn exr_dimensions(path: &Path) -> Result<(u32, u32), DataError> {
    check_exists(path)?;
    let meta = exr::meta::MetaData::read_from_file(path, false).map_err(|e| bad_exr(path, e))?;
    let header = meta
        .headers
        .first()
        .ok_or_else(|| bad_exr(path, "no layer"))?;
    Ok((
        header.layer_size.width() as u32,
        header.layer_size.height() as u32,
    ))
}

/// Writes named float channels (each `width · height` row-major values) as
/// one EXR layer, ZIP compressed, atomically. Used for RGB images and for
/// N-channel maps such as the 9 material parameters (`p0`..`p8`).
pub fn write_exr_channels(
    path: &Path,
    width: u32,
    height: u32,
    channels: &[(&str, &[f32])],
) -> Result<(), DataError> {
    let n = width as usize * height as usize;
    let write_err = |m: String| DataError::WriteImage {
        path: path.to_path_buf(),
        format: "EXR",
        message: m,
    };
    if channels.is_empty() || width == 0 || height == 0 {
        return Err(write_err(format!(
            "nothing to write ({width}x{height}, {} channels)",
            channels.len()
        )));
    }
    for (name, values) in channels {
        if values.len() != n {
            return Err(write_err(format!(
                "channel {name} has {} values, expected {n}",
                values.len()
            )));
        }
        if name.is_empty() {
            return Err(write_err("empty channel name".into()));
        }
    }
    let list = channels
        .iter()
        .map(|(name, values)| AnyChannel::new(*name, FlatSamples::F32(values.to_vec())))
        .collect();
    let layer = Layer::new(
        (width as usize, height as usize),
        LayerAttributes::default(),
        Encoding::SMALL_LOSSLESS,
        AnyChannels::sort(list),
    );
    let image = Image::from_layer(layer);
    write_atomically(path, |w| {
        image
            .write()
            .to_buffered(w)
            .map_err(|e| write_err(e.to_string()))
    })
}

/// Writes a linear RGB image as a float32 EXR with channels R, G, B, atomically.
pub fn write_exr_rgb(path: &Path, image: &RgbImage) -> Result<(), DataError> {
    let n = image.pixel_count();
    if image.data.len() != 3 * n {
        return Err(DataError::WriteImage {
            path: path.to_path_buf(),
            format: "EXR",
            message: format!(
                "image data has {} values, expected {}",
                image.data.len(),
                3 * n
            ),
        });
    }
    let plane = |c: usize| {
        image
            .data
            .iter()
            .skip(c)
            .step_by(3)
            .copied()
            .collect::<Vec<f32>>()
    };
    let (r, g, b) = (plane(0), plane(1), plane(2));
    write_exr_channels(
        path,
        image.width,
        image.height,
        &[("R", &r), ("G", &g), ("B", &b)],
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rgb_round_trip_keeps_channel_identity() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("a.exr");
        let mut img = RgbImage::new(5, 3);
        for (i, v) in img.data.iter_mut().enumerate() {
            *v = i as f32 * 0.25 - 1.0;
        }
        img.set(4, 2, [10.0, 0.0, -3.5]);
        write_exr_rgb(&path, &img).unwrap();
        assert_eq!(exr_dimensions(&path).unwrap(), (5, 3));
        let back = read_exr_rgb(&path).unwrap();
        assert_eq!(back, img);
        let ch = read_exr_channels(&path).unwrap();
        // Stored sorted by name, looked up by name.
        assert_eq!(ch.names(), "B, G, R");
        assert_eq!(ch.channel("R").unwrap()[14], 10.0);
        assert_eq!(ch.channel("B").unwrap()[14], -3.5);
    }

    #[test]
    fn n_channel_round_trip() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("params.exr");
        let planes: Vec<Vec<f32>> = (0..9)
            .map(|c| (0..6).map(|i| c as f32 + 0.1 * i as f32).collect())
            .collect();
        let names: Vec<String> = (0..9).map(|c| format!("p{c}")).collect();
        let chans: Vec<(&str, &[f32])> = names
            .iter()
            .map(String::as_str)
            .zip(planes.iter().map(Vec::as_slice))
            .collect();
        write_exr_channels(&path, 3, 2, &chans).unwrap();
        let back = read_exr_channels(&path).unwrap();
        assert_eq!((back.width, back.height), (3, 2));
        for (c, plane) in planes.iter().enumerate() {
            assert_eq!(back.channel(&format!("p{c}")).unwrap(), plane.as_slice());
        }
        let err = read_exr_rgb(&path).unwrap_err().to_string();
        assert!(
            err.contains("params.exr") && err.contains("no R, G, B channels"),
            "{err}"
        );
    }

    #[test]
    fn wrong_length_is_refused() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("x.exr");
        let err = write_exr_channels(&path, 2, 2, &[("R", &[0.0; 3])])
            .unwrap_err()
            .to_string();
        assert!(err.contains("x.exr") && err.contains("expected 4"), "{err}");
        assert!(!path.exists());
    }

    /// Writes one EXR layer with the given channels, bypassing our writer.
    fn write_raw(path: &Path, w: usize, h: usize, list: Vec<AnyChannel<FlatSamples>>) {
        let layer = Layer::new(
            (w, h),
            LayerAttributes::default(),
            Encoding::UNCOMPRESSED,
            AnyChannels::sort(list.into()),
        );
        Image::from_layer(layer).write().to_file(path).unwrap();
    }

    #[test]
    fn half_float_and_alpha_are_read() {
        use exr::prelude::f16;
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("half.exr");
        let plane = |v: f32| FlatSamples::F16(vec![f16::from_f32(v); 6]);
        let list = vec![
            AnyChannel::new("A", plane(1.0)),
            AnyChannel::new("B", plane(0.25)),
            AnyChannel::new("G", plane(0.5)),
            AnyChannel::new("R", plane(2.0)),
        ];
        write_raw(&path, 3, 2, list);
        let img = read_exr_rgb(&path).unwrap();
        assert_eq!((img.width, img.height), (3, 2));
        assert_eq!(img.get(2, 1), [2.0, 0.5, 0.25]);
    }

    #[test]
    fn luminance_only_is_grey() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("y.exr");
        write_raw(
            &path,
            2,
            1,
            vec![AnyChannel::new("Y", FlatSamples::F32(vec![0.5, 3.0]))],
        );
        let img = read_exr_rgb(&path).unwrap();
        assert_eq!(img.data, vec![0.5, 0.5, 0.5, 3.0, 3.0, 3.0]);
    }
}
