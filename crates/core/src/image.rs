//! Planar f32 images with named channels, and their EXR / PNG I/O.
//!
//! Planar (one contiguous plane per channel) because every consumer works per channel: the
//! network wants NCHW tensors, metrics and previews want single planes.

use std::path::Path;

use crate::color::to_srgb8;
use crate::error::{Error, Result};

type CoreError = Error;

#[derive(Clone, Debug, PartialEq)]
pub struct PlanarImage {
    width: u32,
    height: u32,
    channels: Vec<String>,
    data: Vec<f32>,
}

/// Sample precision used when writing EXR files.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ExrPrecision {
    F32,
    /// Half floats: half the disk, ~3 significant digits (fine for network inputs).
    F16,
}

impl PlanarImage {
    pub fn new(width: u32, height: u32, channels: Vec<String>) -> Self {
        let len = width as usize * height as usize * channels.len();
        PlanarImage { width, height, channels, data: vec![0.0; len] }
    }

    pub fn from_planes(width: u32, height: u32, channels: Vec<String>, data: Vec<f32>) -> Result<Self> {
        let expected = width as usize * height as usize * channels.len();
        if data.len() != expected {
            return Err(Error::Internal(format!("planar image {width}x{height}x{}: got {} samples, expected {expected}", channels.len(), data.len())));
        }
        Ok(PlanarImage { width, height, channels, data })
    }

    pub fn width(&self) -> u32 {
        self.width
    }
    pub fn height(&self) -> u32 {
        self.height
    }
    pub fn pixel_count(&self) -> usize {
        self.width as usize * self.height as usize
    }
    pub fn channels(&self) -> &[String] {
        &self.channels
    }
    pub fn data(&self) -> &[f32] {
        &self.data
    }
    pub fn data_mut(&mut self) -> &mut [f32] {
        &mut self.data
    }

    pub fn channel_index(&self, name: &str) -> Option<usize> {
        self.channels.iter().position(|c| c == name)
    }

    pub fn plane(&self, channel: usize) -> &[f32] {
        let n = self.pixel_count();
        &self.data[channel * n..(channel + 1) * n]
    }

    pub fn plane_mut(&mut self, channel: usize) -> &mut [f32] {
        let n = self.pixel_count();
        &mut self.data[channel * n..(channel + 1) * n]
    }

    pub fn plane_by_name(&self, name: &str) -> Option<&[f32]> {
        self.channel_index(name).map(|c| self.plane(c))
    }

    pub fn get(&self, channel: usize, x: u32, y: u32) -> f32 {
        self.data[channel * self.pixel_count() + (y * self.width + x) as usize]
    }

    pub fn set(&mut self, channel: usize, x: u32, y: u32, value: f32) {
        let n = self.pixel_count();
        self.data[channel * n + (y * self.width + x) as usize] = value;
    }

    /// Stack images of the same size into one (channels concatenated in order).
    pub fn concat(images: &[&PlanarImage]) -> Result<Self> {
        let first = images.first().ok_or_else(|| Error::Internal("concat of no images".into()))?;
        let mut channels = Vec::new();
        let mut data = Vec::new();
        for im in images {
            if (im.width, im.height) != (first.width, first.height) {
                return Err(Error::Internal("concat of images of different sizes".into()));
            }
            channels.extend(im.channels.iter().cloned());
            data.extend_from_slice(&im.data);
        }
        PlanarImage::from_planes(first.width, first.height, channels, data)
    }

    /// A new image holding the named channels, in the given order.
    pub fn select(&self, names: &[String]) -> Result<Self> {
        let mut data = Vec::with_capacity(names.len() * self.pixel_count());
        for name in names {
            let c = self.channel_index(name).ok_or_else(|| Error::Internal(format!("image has no channel {name:?}")))?;
            data.extend_from_slice(self.plane(c));
        }
        PlanarImage::from_planes(self.width, self.height, names.to_vec(), data)
    }

    /// The `width` x `height` window whose top-left pixel is (x, y), all channels.
    pub fn crop(&self, x: u32, y: u32, width: u32, height: u32) -> Result<Self> {
        if x + width > self.width || y + height > self.height {
            return Err(Error::Internal(format!("crop {width}x{height}+{x}+{y} outside a {}x{} image", self.width, self.height)));
        }
        let mut data = Vec::with_capacity(width as usize * height as usize * self.channels.len());
        for c in 0..self.channels.len() {
            let plane = self.plane(c);
            for row in y..y + height {
                let start = (row * self.width + x) as usize;
                data.extend_from_slice(&plane[start..start + width as usize]);
            }
        }
        PlanarImage::from_planes(width, height, self.channels.clone(), data)
    }

    /// Write all channels to an EXR file, atomically (temp file + rename).
    pub fn write_exr(&self, path: &Path, precision: ExrPrecision) -> Result<()> {
        let bytes = self.exr_bytes(precision).map_err(|e| CoreError::Internal(format!("{}: {e}", path.display())))?;
        write_bytes_atomically(path, &bytes)
    }

    /// The bytes of the EXR file [`PlanarImage::write_exr`] writes: all channels, ZIP16,
    /// scan lines in increasing order, so that equal pixels give equal bytes.
    pub fn exr_bytes(&self, precision: ExrPrecision) -> Result<Vec<u8>> {
        self.exr_bytes_labelled(precision, None)
    }

    /// [`PlanarImage::exr_bytes`] with one text attribute `(name, value)` in the header. One
    /// only: the EXR writer (exr 1.74) keeps custom attributes in a hash map and writes them in
    /// its order, which would make the bytes differ from run to run.
    pub fn exr_bytes_labelled(&self, precision: ExrPrecision, label: Option<(&str, &str)>) -> Result<Vec<u8>> {
        use exr::prelude::*;
        let mut attributes = LayerAttributes::default();
        if let Some((name, value)) = label {
            let text = |s: &str| Text::new_or_none(s).ok_or_else(|| CoreError::Internal(format!("EXR attribute text {s:?} is not ASCII")));
            attributes.other.insert(text(name)?, exr::meta::attribute::AttributeValue::Text(text(value)?));
        }
        let channels: Vec<AnyChannel<FlatSamples>> = self
            .channels
            .iter()
            .enumerate()
            .map(|(c, name)| {
                let plane = self.plane(c);
                let samples = match precision {
                    ExrPrecision::F32 => FlatSamples::F32(plane.to_vec()),
                    ExrPrecision::F16 => FlatSamples::F16(plane.iter().map(|&v| half::f16::from_f32(v)).collect()),
                };
                AnyChannel::new(name.as_str(), samples)
            })
            .collect();
        let layer = Layer::new(
            (self.width as usize, self.height as usize),
            attributes,
            // Scan lines in increasing order: the bytes of a file then depend on the pixels
            // alone, not on which compression thread finished first (resume and shard merge
            // compare files byte for byte). ZIP suits float data; every EXR reader knows it.
            Encoding { compression: Compression::ZIP16, blocks: Blocks::ScanLines, line_order: LineOrder::Increasing },
            AnyChannels::sort(channels.into()),
        );
        let image = Image::from_layer(layer);
        let mut bytes = std::io::Cursor::new(Vec::new());
        image.write().to_buffered(&mut bytes).map_err(|e| CoreError::Internal(format!("encoding EXR: {e}")))?;
        Ok(bytes.into_inner())
    }

    /// The text attribute `name` of an EXR file's first header, read without its pixels;
    /// `None` where the file has no such attribute or is not an EXR file.
    pub fn exr_text_attribute(bytes: &[u8], name: &str) -> Option<String> {
        let meta = exr::meta::MetaData::read_from_buffered(std::io::Cursor::new(bytes), false).ok()?;
        let header = meta.headers.first()?;
        let key = exr::meta::attribute::Text::new_or_none(name)?;
        match header.own_attributes.other.get(&key)? {
            exr::meta::attribute::AttributeValue::Text(text) => Some(text.to_string()),
            _ => None,
        }
    }

    /// Read every channel of the first layer of an EXR file (channel order as stored, which
    /// EXR sorts by name; use [`PlanarImage::select`] to get a layout's order).
    pub fn read_exr(path: &Path) -> Result<Self> {
        let bytes = std::fs::read(path).map_err(|e| CoreError::io(path, e))?;
        PlanarImage::read_exr_bytes(&bytes, &path.display())
    }

    /// [`PlanarImage::read_exr`] of a file's bytes already in memory; `source` names the file
    /// in errors.
    pub fn read_exr_bytes(bytes: &[u8], source: &impl std::fmt::Display) -> Result<Self> {
        use exr::prelude::*;
        let image = read()
            .no_deep_data()
            .largest_resolution_level()
            .all_channels()
            .first_valid_layer()
            .all_attributes()
            .from_buffered(std::io::Cursor::new(bytes))
            .map_err(|e| CoreError::bad_input(source, "EXR", e.to_string()))?;
        let size = image.layer_data.size;
        let mut channels = Vec::new();
        let mut data = Vec::with_capacity(size.area() * image.layer_data.channel_data.list.len());
        for ch in image.layer_data.channel_data.list.iter() {
            channels.push(ch.name.to_string());
            match &ch.sample_data {
                FlatSamples::F16(v) => data.extend(v.iter().map(|h| h.to_f32())),
                FlatSamples::F32(v) => data.extend_from_slice(v.as_slice()),
                FlatSamples::U32(v) => data.extend(v.iter().map(|&u| u as f32)),
            }
        }
        PlanarImage::from_planes(size.0 as u32, size.1 as u32, channels, data)
    }

    /// Write three channels as an sRGB PNG after the clamp tone map (see [`crate::color`]).
    pub fn write_png_rgb(&self, path: &Path, rgb: [usize; 3]) -> Result<()> {
        let n = self.pixel_count();
        let mut bytes = Vec::with_capacity(n * 3);
        for i in 0..n {
            for &c in &rgb {
                bytes.push(to_srgb8(self.data[c * n + i]));
            }
        }
        let img = image::RgbImage::from_raw(self.width, self.height, bytes).ok_or_else(|| Error::Internal("PNG buffer size".into()))?;
        write_atomically(path, |tmp| {
            img.save_with_format(tmp, image::ImageFormat::Png).map_err(|e| Error::Internal(format!("{}: writing PNG: {e}", path.display())))
        })
    }

    /// Write one channel as a greyscale PNG, linearly mapping [lo, hi] to [0, 255] (for
    /// non-colour layers such as depth or normals, where sRGB would mislead).
    pub fn write_png_gray(&self, path: &Path, channel: usize, lo: f32, hi: f32) -> Result<()> {
        let scale = if hi > lo { 1.0 / (hi - lo) } else { 0.0 };
        let bytes: Vec<u8> = self.plane(channel).iter().map(|&v| (((v - lo) * scale).clamp(0.0, 1.0) * 255.0 + 0.5) as u8).collect();
        let img = image::GrayImage::from_raw(self.width, self.height, bytes).ok_or_else(|| Error::Internal("PNG buffer size".into()))?;
        write_atomically(path, |tmp| {
            img.save_with_format(tmp, image::ImageFormat::Png).map_err(|e| Error::Internal(format!("{}: writing PNG: {e}", path.display())))
        })
    }
}

/// Write a file through a temporary sibling and rename it into place, so that a reader never
/// sees a half-written file and a killed process leaves nothing at `path`.
pub fn write_atomically(path: &Path, write: impl FnOnce(&Path) -> Result<()>) -> Result<()> {
    if let Some(dir) = path.parent() {
        if !dir.as_os_str().is_empty() {
            std::fs::create_dir_all(dir).map_err(|e| Error::io(dir, e))?;
        }
    }
    let file_name = path.file_name().map(|n| n.to_string_lossy().to_string()).unwrap_or_default();
    let tmp = path.with_file_name(format!(".{file_name}.tmp{}", std::process::id()));
    match write(&tmp) {
        Ok(()) => std::fs::rename(&tmp, path).map_err(|e| Error::io(path, e)),
        Err(e) => {
            let _ = std::fs::remove_file(&tmp);
            Err(e)
        }
    }
}

/// Atomically write bytes to a file.
pub fn write_bytes_atomically(path: &Path, bytes: &[u8]) -> Result<()> {
    write_atomically(path, |tmp| std::fs::write(tmp, bytes).map_err(|e| Error::io(tmp, e)))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn gradient() -> PlanarImage {
        let names = vec!["opaque.depth.Y".to_string(), "opaque.albedo.R".to_string()];
        let mut im = PlanarImage::new(5, 3, names);
        for y in 0..3 {
            for x in 0..5 {
                im.set(0, x, y, x as f32 * 0.5 + y as f32);
                im.set(1, x, y, -(x as f32) * 0.25);
            }
        }
        im
    }

    #[test]
    fn exr_round_trip_f32_is_exact() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("a.exr");
        let im = gradient();
        im.write_exr(&path, ExrPrecision::F32).unwrap();
        let back = PlanarImage::read_exr(&path).unwrap().select(im.channels()).unwrap();
        assert_eq!(back, im);
    }

    #[test]
    fn exr_round_trip_f16_is_close() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("a.exr");
        let im = gradient();
        im.write_exr(&path, ExrPrecision::F16).unwrap();
        let back = PlanarImage::read_exr(&path).unwrap().select(im.channels()).unwrap();
        for (a, b) in back.data().iter().zip(im.data()) {
            assert!((a - b).abs() <= 1e-3 * b.abs().max(1.0));
        }
    }

    #[test]
    fn missing_and_corrupt_exr_are_errors() {
        let dir = tempfile::tempdir().unwrap();
        assert!(PlanarImage::read_exr(&dir.path().join("none.exr")).is_err());
        let bad = dir.path().join("bad.exr");
        std::fs::write(&bad, b"not an exr").unwrap();
        assert!(PlanarImage::read_exr(&bad).is_err());
    }

    #[test]
    fn exr_bytes_depend_on_the_pixels_only() {
        // Large enough for many compressed blocks, which are compressed in parallel.
        let mut im = PlanarImage::new(320, 256, vec!["R".into(), "G".into(), "B".into()]);
        let mut state = 1u64;
        for v in im.data_mut() {
            state = crate::seed::mix64(state);
            *v = (state >> 40) as f32 / (1u64 << 24) as f32;
        }
        let dir = tempfile::tempdir().unwrap();
        let reference = dir.path().join("a.exr");
        im.write_exr(&reference, ExrPrecision::F32).unwrap();
        let expected = std::fs::read(&reference).unwrap();
        for i in 0..8 {
            let path = dir.path().join(format!("b{i}.exr"));
            im.write_exr(&path, ExrPrecision::F32).unwrap();
            assert_eq!(std::fs::read(&path).unwrap(), expected, "write {i} differs");
        }
    }

    #[test]
    fn crop_takes_the_window() {
        let im = gradient();
        let c = im.crop(1, 1, 3, 2).unwrap();
        assert_eq!((c.width(), c.height()), (3, 2));
        for y in 0..2 {
            for x in 0..3 {
                assert_eq!(c.get(0, x, y), im.get(0, x + 1, y + 1));
                assert_eq!(c.get(1, x, y), im.get(1, x + 1, y + 1));
            }
        }
        assert!(im.crop(3, 0, 3, 1).is_err());
    }

    #[test]
    fn select_and_concat() {
        let im = gradient();
        let swapped = im.select(&[im.channels()[1].clone(), im.channels()[0].clone()]).unwrap();
        assert_eq!(swapped.plane(0), im.plane(1));
        let both = PlanarImage::concat(&[&im, &swapped]).unwrap();
        assert_eq!(both.channels().len(), 4);
        assert_eq!(both.plane(3), im.plane(0));
        assert!(im.select(&["missing".to_string()]).is_err());
    }
}
