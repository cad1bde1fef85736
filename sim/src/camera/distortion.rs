//! Lens distortion: the raw image of a lens that is not a pinhole.
//!
//! The model is OpenCV's `plumb_bob` (Brown's 1966 decentering-distortion model with
//! Conrady's radial terms, as OpenCV's camera-calibration documentation and ROS's
//! `sensor_msgs/CameraInfo` state it): a point at normalized image coordinates `(x, y)`
//! (`X/Z`, `Y/Z` in the optical frame) is seen at
//!
//! ```text
//! r² = x² + y²,   radial = 1 + k1 r² + k2 r⁴ + k3 r⁶
//! x_d = x·radial + 2 p1 x y + p2 (r² + 2 x²)
//! y_d = y·radial + p1 (r² + 2 y²) + 2 p2 x y
//! ```
//!
//! and at pixel `(fx x_d + cx, fy y_d + cy)`. The camera renders a pinhole image on a
//! canvas large enough to hold every raw pixel's undistorted ray (the same focal lengths,
//! the principal point moved by the margin), then resamples it: each raw pixel takes the
//! canvas at its undistorted position, colour bilinearly, depth from the nearest canvas
//! pixel (depth is never blended across an edge).

use super::intrinsics::Intrinsics;

/// `plumb_bob` coefficients.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Distortion {
    pub k1: f64,
    pub k2: f64,
    pub p1: f64,
    pub p2: f64,
    pub k3: f64,
}

impl Distortion {
    /// `[k1, k2, p1, p2, k3]`; `None` when all are zero (a pinhole).
    pub fn new(d: [f64; 5]) -> Option<Self> {
        let [k1, k2, p1, p2, k3] = d;
        (d != [0.0; 5]).then_some(Self { k1, k2, p1, p2, k3 })
    }

    /// Where the lens puts the normalized point `(x, y)`.
    pub fn distort(&self, x: f64, y: f64) -> (f64, f64) {
        let r2 = x * x + y * y;
        let radial = 1.0 + r2 * (self.k1 + r2 * (self.k2 + r2 * self.k3));
        (
            x * radial + 2.0 * self.p1 * x * y + self.p2 * (r2 + 2.0 * x * x),
            y * radial + self.p1 * (r2 + 2.0 * y * y) + 2.0 * self.p2 * x * y,
        )
    }

    /// The normalized point the lens puts at `(xd, yd)`: the fixed-point iteration of
    /// OpenCV's `undistortPoints` (`x = (x_d - tangential(x)) / radial(x)`), run until it
    /// moves less than 1e-12; `None` where it does not settle (a lens model that folds).
    pub fn undistort(&self, xd: f64, yd: f64) -> Option<(f64, f64)> {
        let (mut x, mut y) = (xd, yd);
        for _ in 0..200 {
            let r2 = x * x + y * y;
            let radial = 1.0 + r2 * (self.k1 + r2 * (self.k2 + r2 * self.k3));
            if radial <= 0.0 {
                return None;
            }
            let dx = 2.0 * self.p1 * x * y + self.p2 * (r2 + 2.0 * x * x);
            let dy = self.p1 * (r2 + 2.0 * y * y) + 2.0 * self.p2 * x * y;
            let (nx, ny) = ((xd - dx) / radial, (yd - dy) / radial);
            let step = (nx - x).abs().max((ny - y).abs());
            (x, y) = (nx, ny);
            if step < 1e-12 {
                let (ex, ey) = self.distort(x, y);
                return ((ex - xd).abs() < 1e-9 && (ey - yd).abs() < 1e-9).then_some((x, y));
            }
        }
        None
    }

    /// Whether the radial term grows with the radius up to `r_max` (else two rays would
    /// meet at one pixel: a model outside its calibrated field).
    fn radially_monotonic(&self, r_max: f64) -> bool {
        (0..=1000).all(|i| {
            let r = r_max * f64::from(i) / 1000.0;
            let r2 = r * r;
            // d/dr of r (1 + k1 r² + k2 r⁴ + k3 r⁶)
            1.0 + r2 * (3.0 * self.k1 + r2 * (5.0 * self.k2 + r2 * 7.0 * self.k3)) > 0.0
        })
    }
}

/// A raw image's pixels in a pinhole canvas: where each raw pixel's ray meets it.
#[derive(Debug, Clone)]
pub struct Remap {
    /// The pinhole image rendered before resampling: the raw image's focal lengths, its
    /// principal point moved by the margin.
    pub canvas: Intrinsics,
    /// Per raw pixel (row-major), its position in the canvas, pixels.
    src: Vec<[f32; 2]>,
    width: usize,
}

impl Remap {
    /// The canvas and the map for a raw image of intrinsics `k` through `d`; an error when
    /// the model folds within the image or would need a canvas over 4 times the image.
    pub fn new(k: &Intrinsics, d: &Distortion) -> Result<Self, String> {
        let (w, h) = (k.width, k.height);
        let mut src = Vec::with_capacity(w * h);
        let (mut lo, mut hi) = ([f64::INFINITY; 2], [f64::NEG_INFINITY; 2]);
        let mut r_max: f64 = 0.0;
        for v in 0..h {
            for u in 0..w {
                let (xd, yd) = ((u as f64 - k.cx) / k.fx, (v as f64 - k.cy) / k.fy);
                let (x, y) = d
                    .undistort(xd, yd)
                    .ok_or_else(|| format!("the lens model does not invert at pixel ({u}, {v})"))?;
                r_max = r_max.max(x.hypot(y));
                let p = [k.fx * x + k.cx, k.fy * y + k.cy];
                for a in 0..2 {
                    lo[a] = lo[a].min(p[a]);
                    hi[a] = hi[a].max(p[a]);
                }
                src.push(p);
            }
        }
        if !d.radially_monotonic(r_max * 1.01) {
            return Err(
                "the lens model folds within the image (its radial term turns back)".into(),
            );
        }
        // Canvas pixel i is the pinhole's x = i - margin: one pixel beyond every position a
        // raw pixel samples, on each side, so that bilinear sampling stays inside.
        let margin = |lo: f64| ((-lo).ceil() + 1.0).max(0.0) as usize;
        let (ml, mt) = (margin(lo[0]), margin(lo[1]));
        let cw = ml + (hi[0].ceil() as usize + 2).max(w);
        let ch = mt + (hi[1].ceil() as usize + 2).max(h);
        if cw * ch > 4 * w * h {
            return Err(format!(
                "the lens model needs a {cw} x {ch} canvas for a {w} x {h} image: too strong for \
                 the image's field of view"
            ));
        }
        let canvas = Intrinsics {
            width: cw,
            height: ch,
            cx: k.cx + ml as f64,
            cy: k.cy + mt as f64,
            ..*k
        };
        let src = src
            .into_iter()
            .map(|[x, y]| [(x + ml as f64) as f32, (y + mt as f64) as f32])
            .collect();
        Ok(Self {
            canvas,
            src,
            width: w,
        })
    }

    /// One raw row `v` of colour from the canvas's bytes: bilinear, gamma-encoded values
    /// (0-255) as floats.
    pub fn colour_row(&self, canvas_rgb: &[u8], v: usize, out: &mut [[f32; 3]]) {
        let cw = self.canvas.width;
        for (o, &[sx, sy]) in out
            .iter_mut()
            .zip(&self.src[v * self.width..][..self.width])
        {
            let (x0, y0) = (sx.floor(), sy.floor());
            let (fx, fy) = (sx - x0, sy - y0);
            let i = y0 as usize * cw + x0 as usize;
            let at = |j: usize, c: usize| f32::from(canvas_rgb[3 * j + c]);
            for (c, o) in o.iter_mut().enumerate() {
                let top = at(i, c) + fx * (at(i + 1, c) - at(i, c));
                let bottom = at(i + cw, c) + fx * (at(i + cw + 1, c) - at(i + cw, c));
                *o = top + fy * (bottom - top);
            }
        }
    }

    /// The raw image's depth from the canvas's: each pixel the nearest canvas pixel's.
    pub fn depth(&self, canvas_depth: &[f32]) -> Vec<f32> {
        let cw = self.canvas.width;
        self.src
            .iter()
            .map(|&[sx, sy]| canvas_depth[sy.round() as usize * cw + sx.round() as usize])
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// iai_kinect2's calibration of Kinect v2 unit 004429261047's colour camera
    /// (`kinect2_bridge/data/004429261047/calib_color.yaml`).
    const KINECT: [f64; 5] = [0.071678, -0.135537, 0.001590, 0.002403, 0.059487];

    #[test]
    fn undistorting_inverts_the_lens() {
        let d = Distortion::new(KINECT).unwrap();
        for &(x, y) in &[(0.0, 0.0), (0.3, -0.2), (-0.9, 0.6), (0.85, 0.5)] {
            let (xd, yd) = d.distort(x, y);
            let (ux, uy) = d.undistort(xd, yd).unwrap();
            assert!(
                (ux - x).abs() < 1e-10 && (uy - y).abs() < 1e-10,
                "({x}, {y}) distorted to ({xd}, {yd}) came back as ({ux}, {uy})"
            );
        }
        assert_eq!(
            Distortion::new([0.0; 5]),
            None,
            "zero coefficients are a pinhole"
        );
    }

    #[test]
    fn the_canvas_holds_every_raw_pixel_and_a_folding_lens_is_refused() {
        let k = Intrinsics::pinhole(64, 48, 84.1);
        let d = Distortion::new(KINECT).unwrap();
        let r = Remap::new(&k, &d).unwrap();
        assert_eq!((r.canvas.fx, r.canvas.fy), (k.fx, k.fy));
        for (i, &[sx, sy]) in r.src.iter().enumerate() {
            let (u, v) = ((i % 64) as f64, (i / 64) as f64);
            assert!(
                sx >= 0.0
                    && sy >= 0.0
                    && (sx as usize + 1) < r.canvas.width
                    && (sy as usize + 1) < r.canvas.height,
                "raw pixel ({u}, {v}) samples the canvas at ({sx}, {sy}), outside {} x {}",
                r.canvas.width,
                r.canvas.height
            );
            // The canvas position is the undistorted ray's, through the canvas's pinhole.
            let (x, y) = (
                (f64::from(sx) - r.canvas.cx) / k.fx,
                (f64::from(sy) - r.canvas.cy) / k.fy,
            );
            let (xd, yd) = d.distort(x, y);
            assert!(
                (xd * k.fx + k.cx - u).abs() < 1e-3 && (yd * k.fy + k.cy - v).abs() < 1e-3,
                "pixel ({u}, {v}) maps to a ray the lens puts at ({}, {})",
                xd * k.fx + k.cx,
                yd * k.fy + k.cy
            );
        }
        // k1 strongly negative: the radial term turns back inside a wide image.
        let folds = Distortion::new([-0.6, 0.0, 0.0, 0.0, 0.0]).unwrap();
        let err = Remap::new(&Intrinsics::pinhole(64, 48, 120.0), &folds).unwrap_err();
        assert!(err.contains("fold") || err.contains("invert"), "{err}");
    }
}
