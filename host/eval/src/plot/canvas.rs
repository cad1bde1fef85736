//! An RGB raster canvas in world coordinates, saved as PNG.

use std::path::Path;

use super::{Bounds, Drawing, Mapping, Rgb};
use crate::EvalError;

/// An RGB raster picture (white at start) onto which world `bounds` are mapped uniformly.
#[derive(Debug, Clone, PartialEq)]
pub struct Canvas {
    mapping: Mapping,
    pixels: Vec<u8>,
}

impl Canvas {
    /// A white `width_px × height_px` canvas showing `bounds` (centred, undistorted).
    pub fn new(width_px: u32, height_px: u32, bounds: Bounds) -> Self {
        Self {
            mapping: Mapping::new(width_px, height_px, bounds),
            pixels: vec![255; width_px as usize * height_px as usize * 3],
        }
    }

    /// The world-to-pixel mapping.
    pub fn mapping(&self) -> &Mapping {
        &self.mapping
    }

    /// The colour of pixel `(x, y)` (x right, y down); `None` outside.
    pub fn pixel(&self, x: u32, y: u32) -> Option<Rgb> {
        (x < self.mapping.width() && y < self.mapping.height()).then(|| {
            let i = 3 * (y as usize * self.mapping.width() as usize + x as usize);
            [self.pixels[i], self.pixels[i + 1], self.pixels[i + 2]]
        })
    }

    /// The raw RGB bytes, row by row from the top.
    pub fn rgb_bytes(&self) -> &[u8] {
        &self.pixels
    }

    /// Fills the whole canvas with `color`.
    pub fn clear(&mut self, color: Rgb) {
        for px in self.pixels.chunks_exact_mut(3) {
            px.copy_from_slice(&color);
        }
    }

    /// A polyline through world `points`, `width_px` wide (round caps and joins).
    pub fn polyline(&mut self, points: &[(f64, f64)], color: Rgb, width_px: f64) {
        let radius = (width_px / 2.0).max(0.5);
        let px: Vec<_> = points.iter().map(|&p| self.mapping.to_pixel(p)).collect();
        if let [only] = px.as_slice() {
            self.disc(*only, radius, color);
        }
        for w in px.windows(2) {
            self.capsule(w[0], w[1], radius, color);
        }
    }

    /// A filled rectangle between world corners `min` and `max`.
    pub fn fill_rect(&mut self, min: (f64, f64), max: (f64, f64), color: Rgb) {
        let (a, b) = (self.mapping.to_pixel(min), self.mapping.to_pixel(max));
        let (x0, x1) = (a.0.min(b.0), a.0.max(b.0));
        let (y0, y1) = (a.1.min(b.1), a.1.max(b.1));
        self.for_pixels_in(
            (x0, y0),
            (x1, y1),
            |x, y| x >= x0 && x <= x1 && y >= y0 && y <= y1,
            color,
        );
    }

    /// A filled circle of `radius_px` pixels around world `center`.
    pub fn circle(&mut self, center: (f64, f64), radius_px: f64, color: Rgb) {
        self.disc(self.mapping.to_pixel(center), radius_px, color);
    }

    /// Writes the canvas as an 8-bit RGB PNG.
    pub fn save_png(&self, path: impl AsRef<Path>) -> Result<(), EvalError> {
        let path = path.as_ref();
        let encode_error = |e: png::EncodingError| EvalError::Encode {
            path: path.to_path_buf(),
            message: e.to_string(),
        };
        let file = crate::io::create(path)?;
        let mut encoder = png::Encoder::new(file, self.mapping.width(), self.mapping.height());
        encoder.set_color(png::ColorType::Rgb);
        encoder.set_depth(png::BitDepth::Eight);
        let mut writer = encoder.write_header().map_err(encode_error)?;
        writer
            .write_image_data(&self.pixels)
            .map_err(encode_error)?;
        writer.finish().map_err(encode_error)
    }

    fn disc(&mut self, c: (f64, f64), radius: f64, color: Rgb) {
        let r2 = radius * radius;
        self.for_pixels_in(
            (c.0 - radius, c.1 - radius),
            (c.0 + radius, c.1 + radius),
            |x, y| (x - c.0).powi(2) + (y - c.1).powi(2) <= r2,
            color,
        );
    }

    /// Pixels whose centres lie within `radius` of the segment `a`–`b`.
    fn capsule(&mut self, a: (f64, f64), b: (f64, f64), radius: f64, color: Rgb) {
        let (dx, dy) = (b.0 - a.0, b.1 - a.1);
        let len2 = dx * dx + dy * dy;
        let r2 = radius * radius;
        self.for_pixels_in(
            (a.0.min(b.0) - radius, a.1.min(b.1) - radius),
            (a.0.max(b.0) + radius, a.1.max(b.1) + radius),
            |x, y| {
                let t = if len2 > 0.0 {
                    (((x - a.0) * dx + (y - a.1) * dy) / len2).clamp(0.0, 1.0)
                } else {
                    0.0
                };
                (x - a.0 - t * dx).powi(2) + (y - a.1 - t * dy).powi(2) <= r2
            },
            color,
        );
    }

    /// Sets the pixels in the pixel-space box whose centre passes `inside`.
    fn for_pixels_in(
        &mut self,
        lo: (f64, f64),
        hi: (f64, f64),
        inside: impl Fn(f64, f64) -> bool,
        color: Rgb,
    ) {
        let (w, h) = (self.mapping.width() as i64, self.mapping.height() as i64);
        let clamp = |v: f64, max: i64| (v.floor() as i64).clamp(0, max - 1);
        if w == 0 || h == 0 || !(lo.0 < w as f64 && lo.1 < h as f64 && hi.0 >= 0.0 && hi.1 >= 0.0) {
            return;
        }
        for y in clamp(lo.1, h)..=clamp(hi.1, h) {
            for x in clamp(lo.0, w)..=clamp(hi.0, w) {
                if inside(x as f64 + 0.5, y as f64 + 0.5) {
                    let i = 3 * (y * w + x) as usize;
                    self.pixels[i..i + 3].copy_from_slice(&color);
                }
            }
        }
    }
}

impl Drawing for Canvas {
    fn polyline(&mut self, points: &[(f64, f64)], color: Rgb, width_px: f64) {
        Canvas::polyline(self, points, color, width_px);
    }
    fn fill_rect(&mut self, min: (f64, f64), max: (f64, f64), color: Rgb) {
        Canvas::fill_rect(self, min, max, color);
    }
    fn circle(&mut self, center: (f64, f64), radius_px: f64, color: Rgb) {
        Canvas::circle(self, center, radius_px, color);
    }
    fn bounds_mapping(&self) -> &Mapping {
        &self.mapping
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn primitives_land_where_the_mapping_says() {
        // 100×50 px showing 0..10 × 0..5 m: 10 px per metre, y up.
        let mut c = Canvas::new(100, 50, Bounds::new((0.0, 0.0), (10.0, 5.0)));
        assert_eq!(c.mapping().px_per_unit(), 10.0, "expected 10 px/m");
        c.fill_rect((0.0, 0.0), (1.0, 1.0), [255, 0, 0]);
        assert_eq!(
            c.pixel(5, 45),
            Some([255, 0, 0]),
            "expected the bottom-left metre red"
        );
        assert_eq!(
            c.pixel(15, 45),
            Some([255, 255, 255]),
            "expected white right of it"
        );
        c.polyline(&[(2.0, 2.5), (8.0, 2.5)], [0, 0, 255], 3.0);
        assert_eq!(
            c.pixel(50, 25),
            Some([0, 0, 255]),
            "expected the line through the centre"
        );
        assert_eq!(
            c.pixel(50, 20),
            Some([255, 255, 255]),
            "expected white 5 px off a 3 px line"
        );
        c.circle((9.0, 4.0), 2.0, [0, 255, 0]);
        assert_eq!(
            c.pixel(90, 10),
            Some([0, 255, 0]),
            "expected the circle at (9, 4) m"
        );
        assert_eq!(c.pixel(100, 0), None, "expected None outside");
    }

    #[test]
    fn png_round_trip_size() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("c.png");
        let c = Canvas::new(7, 3, Bounds::new((0.0, 0.0), (1.0, 1.0)));
        c.save_png(&path).unwrap();
        let decoder =
            png::Decoder::new(std::io::BufReader::new(std::fs::File::open(&path).unwrap()));
        let info = decoder.read_info().unwrap();
        assert_eq!(
            (info.info().width, info.info().height),
            (7, 3),
            "expected a 7×3 PNG"
        );
    }
}
