//! An SVG writer with the primitives of [`super::Canvas`], plus text.

use std::fmt::Write as _;
use std::path::Path;

use super::{Bounds, Drawing, Mapping, Rgb};
use crate::EvalError;

/// An SVG picture (white background) onto which world `bounds` are mapped uniformly.
#[derive(Debug, Clone, PartialEq)]
pub struct Svg {
    mapping: Mapping,
    body: String,
}

fn hex(c: Rgb) -> String {
    format!("#{:02x}{:02x}{:02x}", c[0], c[1], c[2])
}

impl Svg {
    /// A white `width_px × height_px` picture showing `bounds` (centred, undistorted).
    pub fn new(width_px: u32, height_px: u32, bounds: Bounds) -> Self {
        let mut svg = Self {
            mapping: Mapping::new(width_px, height_px, bounds),
            body: String::new(),
        };
        let _ = writeln!(
            svg.body,
            r#"<rect width="100%" height="100%" fill="white"/>"#
        );
        svg
    }

    /// The world-to-pixel mapping.
    pub fn mapping(&self) -> &Mapping {
        &self.mapping
    }

    /// A polyline through world `points`, `width_px` wide (round caps and joins).
    pub fn polyline(&mut self, points: &[(f64, f64)], color: Rgb, width_px: f64) {
        let mut coords = String::new();
        for &p in points {
            let (x, y) = self.mapping.to_pixel(p);
            let _ = write!(coords, "{x:.2},{y:.2} ");
        }
        let _ = writeln!(
            self.body,
            r#"<polyline points="{}" fill="none" stroke="{}" stroke-width="{width_px}" stroke-linecap="round" stroke-linejoin="round"/>"#,
            coords.trim_end(),
            hex(color)
        );
    }

    /// A filled rectangle between world corners `min` and `max`.
    pub fn fill_rect(&mut self, min: (f64, f64), max: (f64, f64), color: Rgb) {
        let (a, b) = (self.mapping.to_pixel(min), self.mapping.to_pixel(max));
        let _ = writeln!(
            self.body,
            r#"<rect x="{:.2}" y="{:.2}" width="{:.2}" height="{:.2}" fill="{}"/>"#,
            a.0.min(b.0),
            a.1.min(b.1),
            (a.0 - b.0).abs(),
            (a.1 - b.1).abs(),
            hex(color)
        );
    }

    /// A filled circle of `radius_px` pixels around world `center`.
    pub fn circle(&mut self, center: (f64, f64), radius_px: f64, color: Rgb) {
        let (x, y) = self.mapping.to_pixel(center);
        let _ = writeln!(
            self.body,
            r#"<circle cx="{x:.2}" cy="{y:.2}" r="{radius_px}" fill="{}"/>"#,
            hex(color)
        );
    }

    /// Text with its baseline starting at world point `at`.
    pub fn text(&mut self, at: (f64, f64), size_px: f64, color: Rgb, text: &str) {
        let (x, y) = self.mapping.to_pixel(at);
        let escaped = text
            .replace('&', "&amp;")
            .replace('<', "&lt;")
            .replace('>', "&gt;");
        let _ = writeln!(
            self.body,
            r#"<text x="{x:.2}" y="{y:.2}" font-family="sans-serif" font-size="{size_px}" fill="{}">{escaped}</text>"#,
            hex(color)
        );
    }

    /// The complete SVG document.
    pub fn to_svg_string(&self) -> String {
        format!(
            "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"{w}\" height=\"{h}\" viewBox=\"0 0 {w} {h}\">\n{}</svg>\n",
            self.body,
            w = self.mapping.width(),
            h = self.mapping.height()
        )
    }

    /// Writes the SVG document to `path`.
    pub fn save(&self, path: impl AsRef<Path>) -> Result<(), EvalError> {
        let path = path.as_ref();
        std::fs::write(path, self.to_svg_string())
            .map_err(|source| crate::io::write_error(path, source))
    }
}

impl Drawing for Svg {
    fn polyline(&mut self, points: &[(f64, f64)], color: Rgb, width_px: f64) {
        Svg::polyline(self, points, color, width_px);
    }
    fn fill_rect(&mut self, min: (f64, f64), max: (f64, f64), color: Rgb) {
        Svg::fill_rect(self, min, max, color);
    }
    fn circle(&mut self, center: (f64, f64), radius_px: f64, color: Rgb) {
        Svg::circle(self, center, radius_px, color);
    }
    fn bounds_mapping(&self) -> &Mapping {
        &self.mapping
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn elements_in_pixel_coordinates() {
        let mut svg = Svg::new(100, 50, Bounds::new((0.0, 0.0), (10.0, 5.0)));
        svg.polyline(&[(0.0, 0.0), (10.0, 5.0)], [255, 0, 0], 2.0);
        svg.circle((5.0, 2.5), 3.0, [0, 0, 0]);
        svg.text((1.0, 1.0), 12.0, [0, 0, 0], "a<b");
        let s = svg.to_svg_string();
        assert!(
            s.contains(r#"points="0.00,50.00 100.00,0.00""#),
            "expected y flipped pixel coordinates in {s}"
        );
        assert!(
            s.contains(r#"<circle cx="50.00" cy="25.00" r="3""#),
            "expected the circle at the centre in {s}"
        );
        assert!(s.contains("a&lt;b"), "expected escaped text in {s}");
    }
}
