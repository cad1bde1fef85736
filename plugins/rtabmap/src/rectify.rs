//! Rectifying a lens's raw frames (`Rtabmap/ImagesAlreadyRectified = false`): the pinhole
//! image of the same camera matrix, each of its pixels taken from where the lens put its ray
//! (OpenCV's `initUndistortRectifyMap` with no rotation and the same camera matrix, then
//! `remap`, which RTAB-Map's `CameraModel::rectifyImage` runs; depth from the nearest raw
//! pixel, never blended across an edge, as its `rectifyDepth` keeps it).

use plugin_api::{Lens, Pinhole};

/// Where each rectified pixel comes from in the raw image.
#[derive(Debug, Clone)]
pub struct Rectifier {
    width: usize,
    height: usize,
    /// Per rectified pixel (row-major), its raw position, px; outside the raw image: none.
    src: Vec<Option<[f32; 2]>>,
}

impl Rectifier {
    pub fn new(k: &Pinhole, lens: &Lens) -> Self {
        let (w, h) = (k.width as usize, k.height as usize);
        let mut src = Vec::with_capacity(w * h);
        for v in 0..h {
            for u in 0..w {
                let (xd, yd) = lens.distort((u as f64 - k.cx) / k.fx, (v as f64 - k.cy) / k.fy);
                let (su, sv) = (k.fx * xd + k.cx, k.fy * yd + k.cy);
                let inside = su >= 0.0 && sv >= 0.0 && su <= (w - 1) as f64 && sv <= (h - 1) as f64;
                src.push(inside.then_some([su as f32, sv as f32]));
            }
        }
        Self {
            width: w,
            height: h,
            src,
        }
    }

    /// The rectified colour (RGB8) and depth (m; 0 where none) of a raw frame.
    pub fn rectify(&self, rgb: &[u8], depth_m: &[f32]) -> (Vec<u8>, Vec<f32>) {
        let (w, h) = (self.width, self.height);
        let mut out_rgb = vec![0u8; 3 * w * h];
        let mut out_depth = vec![0.0f32; w * h];
        for (i, s) in self.src.iter().enumerate() {
            let Some([su, sv]) = *s else {
                continue;
            };
            let (x0, y0) = (su.floor() as usize, sv.floor() as usize);
            let (x1, y1) = ((x0 + 1).min(w - 1), (y0 + 1).min(h - 1));
            let (fx, fy) = (su - x0 as f32, sv - y0 as f32);
            for c in 0..3 {
                let at = |x: usize, y: usize| f32::from(rgb[3 * (y * w + x) + c]);
                let top = at(x0, y0) + fx * (at(x1, y0) - at(x0, y0));
                let bottom = at(x0, y1) + fx * (at(x1, y1) - at(x0, y1));
                out_rgb[3 * i + c] = (top + fy * (bottom - top)).round().clamp(0.0, 255.0) as u8;
            }
            out_depth[i] = depth_m[(sv.round() as usize) * w + su.round() as usize];
        }
        (out_rgb, out_depth)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A raw image made by a lens from a pinhole image comes back: a bright dot moved by
    /// the lens to another pixel is rectified to where the pinhole saw it, with its depth.
    #[test]
    fn rectifying_puts_a_point_back_where_the_pinhole_saw_it() {
        let k = Pinhole {
            fx: 300.0,
            fy: 300.0,
            cx: 159.5,
            cy: 119.5,
            width: 320.0,
            height: 240.0,
        };
        let lens = Lens {
            k1: -0.25,
            k2: 0.05,
            p1: 0.001,
            p2: -0.001,
            k3: 0.0,
        };
        // The pinhole pixel (280, 200) seen through the lens.
        let (u, v) = (280.0f64, 200.0f64);
        let (xd, yd) = lens.distort((u - k.cx) / k.fx, (v - k.cy) / k.fy);
        let (ru, rv) = (
            (k.fx * xd + k.cx).round() as usize,
            (k.fy * yd + k.cy).round() as usize,
        );
        assert!(
            (ru as f64 - u).hypot(rv as f64 - v) > 5.0,
            "the lens moves it"
        );
        // A 3 x 3 white square at the raw position, depth 2 m there and 5 m elsewhere.
        let (w, h) = (320, 240);
        let mut rgb = vec![0u8; 3 * w * h];
        let mut depth = vec![5.0f32; w * h];
        for dv in 0..3 {
            for du in 0..3 {
                let i = (rv + dv - 1) * w + ru + du - 1;
                rgb[3 * i..3 * i + 3].fill(255);
                depth[i] = 2.0;
            }
        }
        let (out_rgb, out_depth) = Rectifier::new(&k, &lens).rectify(&rgb, &depth);
        let i = v as usize * w + u as usize;
        assert_eq!(
            out_rgb[3 * i],
            255,
            "the dot is back at the pinhole's pixel"
        );
        assert_eq!(out_depth[i], 2.0);
        assert_eq!(
            out_depth[(v as usize - 6) * w + u as usize],
            5.0,
            "and only there"
        );
    }
}
