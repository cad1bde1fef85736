//! The camera's output frame and PNG writers for looking at it.

use std::fs::File;
use std::io::BufWriter;
use std::path::Path;

use crate::error::SimError;

/// One RGB-D frame: colour and depth registered pixel for pixel, row-major from the top
/// left. See [`crate::camera`] for the frames and the invalid-depth convention.
#[derive(Debug, Clone, PartialEq)]
pub struct RgbdImage {
    pub width: usize,
    pub height: usize,
    /// RGB8, `3 * width * height` bytes.
    pub rgb: Vec<u8>,
    /// Depth along the optical axis in metres; 0 where invalid.
    pub depth_m: Vec<f32>,
    /// Pinhole `[fx, fy, cx, cy]` in pixels, optical frame (z forward, x right, y down).
    pub intrinsics: [f64; 4],
}

/// Writes the colour image as an 8-bit RGB PNG.
pub fn save_rgb_png(path: &Path, image: &RgbdImage) -> Result<(), SimError> {
    write_png(path, image.width, image.height, &image.rgb)
}

/// Writes the depth image colourised with the turbo colour map from 0 (blue) to
/// `max_depth_m` (red); invalid pixels are black.
pub fn save_depth_png(path: &Path, image: &RgbdImage, max_depth_m: f32) -> Result<(), SimError> {
    let mut rgb = Vec::with_capacity(3 * image.depth_m.len());
    for &z in &image.depth_m {
        if z > 0.0 {
            rgb.extend_from_slice(&turbo(z / max_depth_m));
        } else {
            rgb.extend_from_slice(&[0, 0, 0]);
        }
    }
    write_png(path, image.width, image.height, &rgb)
}

/// Google's Turbo colour map at `x` in [0, 1], by its published polynomial approximation
/// (Mikhailov 2019).
pub fn turbo(x: f32) -> [u8; 3] {
    let x = x.clamp(0.0, 1.0);
    let poly = |c: [f32; 6]| c[0] + x * (c[1] + x * (c[2] + x * (c[3] + x * (c[4] + x * c[5]))));
    let r = poly([
        0.135_721_38,
        4.615_392_6,
        -42.660_324,
        132.131_08,
        -152.942_4,
        59.286_38,
    ]);
    let g = poly([
        0.091_402_61,
        2.194_188_4,
        4.842_966_6,
        -14.185_033,
        4.277_298_5,
        2.829_566,
    ]);
    let b = poly([
        0.106_673_3,
        12.641_946,
        -60.582_05,
        110.362_77,
        -89.903_11,
        27.348_25,
    ]);
    [r, g, b].map(|c| (c.clamp(0.0, 1.0) * 255.0).round() as u8)
}

fn write_png(path: &Path, width: usize, height: usize, rgb: &[u8]) -> Result<(), SimError> {
    let io = |source: std::io::Error| SimError::Io {
        path: path.to_owned(),
        source,
    };
    let file = File::create(path).map_err(io)?;
    let mut encoder = png::Encoder::new(BufWriter::new(file), width as u32, height as u32);
    encoder.set_color(png::ColorType::Rgb);
    encoder.set_depth(png::BitDepth::Eight);
    encoder.set_compression(png::Compression::High);
    let mut writer = encoder
        .write_header()
        .map_err(|e| io(std::io::Error::other(e)))?;
    writer
        .write_image_data(rgb)
        .map_err(|e| io(std::io::Error::other(e)))?;
    writer.finish().map_err(|e| io(std::io::Error::other(e)))
}
