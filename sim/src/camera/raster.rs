//! Projection and z-buffered scan conversion into a visibility buffer.
//!
//! A projected triangle carries a plane `q(x, y)` that is affine in screen space: `1 / z`
//! for the perspective camera (Heckbert & Moreton 1991), the height towards the sun for the
//! orthographic shadow map. Both keep the largest `q` (the nearest surface); equal `q` go to
//! the smaller triangle index, so the result never depends on drawing order.
//!
//! Multisampling ([`rasterize_band_ms`]): a pixel holds one visibility sample per offset
//! of a [`SAMPLES_4`]-like pattern, its samples side by side (`[row][column][sample]`).
//! Every offset has its own row offset, so each sample of a pixel row lies on a scan line
//! of its own: per pixel row, a triangle's span on each sample's scan line is converted to
//! the columns whose sample it covers (all samples at once, lane by lane), and each column
//! between the first and the last of them is depth-tested for all its samples at once. A
//! triangle is kept when it covers any sample, so thin wires and far leaves that fall
//! between pixel centres still show.

use std::ops::Range;

use nalgebra::Isometry3;
use rayon::prelude::*;

use super::chunks::Chunks;
use super::intrinsics::Intrinsics;
use super::lanes::F4;

/// Near clipping plane of the renderer (the depth image's own limit is applied later).
pub(crate) const NEAR_M: f32 = 0.05;

/// Widening of every edge, in pixels: shared edges computed with different rounding never
/// leave a crack.
const EDGE_EPS: f32 = 1e-4;

/// One sample at the pixel centre: no anti-aliasing.
pub(crate) const SAMPLES_1: [[f32; 2]; 1] = [[0.0, 0.0]];
/// Direct3D's standard 4x multisample pattern (`D3D11_STANDARD_MULTISAMPLE_PATTERN`), a
/// rotated grid: offsets from the pixel centre in pixels, x right and y down, each sample
/// on a row and a column of its own (the positions in 1/16 pixel: (-2, -6), (6, -2),
/// (-6, 2), (2, 6)). The offsets sum to zero, so the centroid of a fully covered pixel is
/// its centre.
pub(crate) const SAMPLES_4: [[f32; 2]; 4] = [
    [-0.125, -0.375],
    [0.375, -0.125],
    [-0.375, 0.125],
    [0.125, 0.375],
];
/// Direct3D's standard 8x pattern, in 1/16 pixel: (1, -3), (-1, 3), (5, 1), (-3, -5),
/// (-5, 5), (-7, -1), (3, 7), (7, -7); every sample on a row of its own, summing to zero.
pub(crate) const SAMPLES_8: [[f32; 2]; 8] = [
    [0.0625, -0.1875],
    [-0.0625, 0.1875],
    [0.3125, 0.0625],
    [-0.1875, -0.3125],
    [-0.3125, 0.3125],
    [-0.4375, -0.0625],
    [0.1875, 0.4375],
    [0.4375, -0.4375],
];

/// The sample pattern of `samples` samples per pixel (1, 4 or 8; the configuration checks).
pub(crate) fn pattern(samples: usize) -> &'static [[f32; 2]] {
    match samples {
        8 => &SAMPLES_8,
        4 => &SAMPLES_4,
        _ => &SAMPLES_1,
    }
}

/// How far a pattern's samples lie from the pixel centre along x or y, at most.
pub(crate) fn reach(pattern: &[[f32; 2]]) -> f32 {
    pattern
        .iter()
        .flatten()
        .fold(0.0f32, |m, &o| m.max(o.abs()))
}

/// A camera pose and pinhole, prepared for projecting world points (f32).
#[derive(Debug, Clone)]
pub(crate) struct View {
    /// Optical centre in the world frame.
    pub origin: [f32; 3],
    /// Rows of `optical_from_world`'s rotation = columns of `world_from_optical`'s: the
    /// optical x, y, z axes in the world frame.
    pub axes: [[f32; 3]; 3],
    pub fx: f32,
    pub fy: f32,
    pub cx: f32,
    pub cy: f32,
    pub inv_fx: f32,
    pub inv_fy: f32,
    pub width: usize,
    pub height: usize,
    /// Frustum planes in the world frame: inside when `n · p + d >= 0`.
    planes: [([f32; 3], f32); 5],
    /// With [`View::culling_beyond`]: the optical-axis depth beyond which whole chunks and
    /// triangles are left out (`f32::INFINITY`: none are).
    cull_beyond: f32,
}

/// How far past a far plane culling starts, relative to its distance: a triangle wholly
/// beyond the plane is still rasterized if it comes this close, so that no sample the
/// interpolated 1 / z (a few ulps off the exact value) would put in front of the plane is
/// lost. Culling is then exact: whatever the pass draws beyond the plane it discards.
const CULL_MARGIN: f32 = 1e-3;

pub(crate) fn dot(a: &[f32; 3], b: &[f32; 3]) -> f32 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

pub(crate) fn sub(a: &[f32; 3], b: &[f32; 3]) -> [f32; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

pub(crate) fn cross(a: &[f32; 3], b: &[f32; 3]) -> [f32; 3] {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

impl View {
    pub fn new(world_from_optical: &Isometry3<f64>, k: &Intrinsics) -> Self {
        let r = world_from_optical.rotation.to_rotation_matrix();
        let m = r.matrix();
        let axes = [0, 1, 2].map(|c| [m[(0, c)] as f32, m[(1, c)] as f32, m[(2, c)] as f32]);
        let t = world_from_optical.translation.vector;
        let origin = [t.x as f32, t.y as f32, t.z as f32];
        // Side planes through the outer pixel edges, as normals in the optical frame.
        let left = ((k.cx + 0.5) / k.fx) as f32;
        let right = ((k.width as f64 - 0.5 - k.cx) / k.fx) as f32;
        let top = ((k.cy + 0.5) / k.fy) as f32;
        let bottom = ((k.height as f64 - 0.5 - k.cy) / k.fy) as f32;
        let to_world = |n: [f32; 3]| -> [f32; 3] {
            [0, 1, 2].map(|d| axes[0][d] * n[0] + axes[1][d] * n[1] + axes[2][d] * n[2])
        };
        let plane = |n_opt: [f32; 3], offset: f32| {
            let n = to_world(n_opt);
            (n, -dot(&n, &origin) - offset)
        };
        let planes = [
            plane([0.0, 0.0, 1.0], NEAR_M),
            plane([1.0, 0.0, left], 0.0),
            plane([-1.0, 0.0, right], 0.0),
            plane([0.0, 1.0, top], 0.0),
            plane([0.0, -1.0, bottom], 0.0),
        ];
        Self {
            origin,
            axes,
            fx: k.fx as f32,
            fy: k.fy as f32,
            cx: k.cx as f32,
            cy: k.cy as f32,
            inv_fx: (1.0 / k.fx) as f32,
            inv_fy: (1.0 / k.fy) as f32,
            width: k.width,
            height: k.height,
            planes,
            cull_beyond: f32::INFINITY,
        }
    }

    /// The same view, leaving out what lies wholly beyond optical-axis depth `far_m` (with
    /// a margin, [`CULL_MARGIN`]): for a pass that discards everything beyond `far_m`
    /// anyway (a far clip plane, a depth camera's range), so the output is the same.
    pub fn culling_beyond(mut self, far_m: f32) -> Self {
        self.cull_beyond = far_m * (1.0 + CULL_MARGIN);
        self
    }

    /// Whether an axis-aligned box may meet the frustum (conservative), and with
    /// [`View::culling_beyond`] come nearer than its depth.
    pub fn box_visible(&self, lo: &[f32; 3], hi: &[f32; 3]) -> bool {
        let beside = |n: &[f32; 3], d: f32| {
            let p = [0, 1, 2].map(|k| if n[k] >= 0.0 { hi[k] } else { lo[k] });
            dot(n, &p) + d >= 0.0
        };
        self.planes.iter().all(|(n, d)| beside(n, *d))
            && (self.cull_beyond == f32::INFINITY || {
                // The far plane: inside when the optical z is at most `cull_beyond`.
                let n = self.axes[2].map(|c| -c);
                beside(&n, self.cull_beyond + dot(&self.axes[2], &self.origin))
            })
    }

    /// A world point in the optical frame.
    pub fn to_optical(&self, p: &[f32; 3]) -> [f32; 3] {
        let r = sub(p, &self.origin);
        [
            dot(&self.axes[0], &r),
            dot(&self.axes[1], &r),
            dot(&self.axes[2], &r),
        ]
    }

    /// Direction of the ray through pixel (u, v) in the world frame, scaled so that its
    /// optical z component is 1.
    pub fn ray(&self, u: f32, v: f32) -> [f32; 3] {
        let x = (u - self.cx) * self.inv_fx;
        let y = (v - self.cy) * self.inv_fy;
        [0, 1, 2].map(|d| self.axes[0][d] * x + self.axes[1][d] * y + self.axes[2][d])
    }
}

/// Floor and ceiling to i32 without a libm call (baseline x86-64 lacks SSE4.1 `roundps`);
/// the span bounds are clamped to the raster before, so they fit.
fn floor_i(x: f32) -> i32 {
    let i = x as i32;
    if (i as f32) > x { i - 1 } else { i }
}

fn ceil_i(x: f32) -> i32 {
    let i = x as i32;
    if (i as f32) < x { i + 1 } else { i }
}

/// A triangle in screen space, ready for scan conversion.
#[derive(Debug, Clone, Copy)]
pub(crate) struct ScreenTri {
    x: [f32; 3],
    y: [f32; 3],
    /// `q = q0 + qx (x - x0) + qy (y - y0)`.
    q0: f32,
    qx: f32,
    qy: f32,
    /// Per edge `k` (from corner `k` to `k + 1`): `x = x[k] + slope (y - y[k])` on it, and
    /// `side`: +1 if it bounds the span on the right, -1 on the left; for a horizontal edge
    /// (0), `flat` is the sign of `(y - y[k])` on its inner side.
    slope: [f32; 3],
    side: [i8; 3],
    flat: [f32; 3],
    pub id: u32,
    x_lo: i32,
    x_hi: i32,
    pub y_lo: i32,
    pub y_hi: i32,
}

impl ScreenTri {
    /// `None` when the triangle is degenerate or surely covers no sample of a
    /// `width x height` raster whose samples lie within `reach` pixels of the pixel centres
    /// along x and y (0: pixel centres only). The bounds are pixel indices.
    pub fn new(
        x: [f32; 3],
        y: [f32; 3],
        q: [f32; 3],
        id: u32,
        (width, height): (usize, usize),
        reach: f32,
    ) -> Option<Self> {
        let (dx1, dy1) = (x[1] - x[0], y[1] - y[0]);
        let (dx2, dy2) = (x[2] - x[0], y[2] - y[0]);
        let area2 = dx1 * dy2 - dx2 * dy1;
        if area2.abs() < 1e-12 || !area2.is_finite() {
            return None;
        }
        let min = |a: [f32; 3]| a[0].min(a[1]).min(a[2]);
        let max = |a: [f32; 3]| a[0].max(a[1]).max(a[2]);
        let x_lo = ((min(x) - reach - EDGE_EPS).ceil().max(0.0)) as i32;
        let x_hi = ((max(x) + reach + EDGE_EPS).floor().min(width as f32 - 1.0)) as i32;
        let y_lo = ((min(y) - reach - EDGE_EPS).ceil().max(0.0)) as i32;
        let y_hi = ((max(y) + reach + EDGE_EPS).floor().min(height as f32 - 1.0)) as i32;
        if x_lo > x_hi || y_lo > y_hi {
            return None;
        }
        let (dq1, dq2) = (q[1] - q[0], q[2] - q[0]);
        let sign = area2.signum();
        let (mut slope, mut side, mut flat) = ([0.0; 3], [0i8; 3], [0.0; 3]);
        for k in 0..3 {
            let j = (k + 1) % 3;
            let (dx, dy) = (x[j] - x[k], y[j] - y[k]);
            // Inside: sign * (dx (y - ay) - dy (x - ax)) >= 0.
            let m = sign * dy;
            if m != 0.0 {
                slope[k] = dx / dy;
                side[k] = if m > 0.0 { 1 } else { -1 };
            } else {
                flat[k] = sign * dx;
            }
        }
        Some(Self {
            x,
            y,
            q0: q[0],
            qx: (dq1 * dy2 - dq2 * dy1) / area2,
            qy: (dq2 * dx1 - dq1 * dx2) / area2,
            slope,
            side,
            flat,
            id,
            x_lo,
            x_hi,
            y_lo,
            y_hi,
        })
    }

    /// The pixel columns whose sample at `(column + dx, py)` lies inside the triangle.
    fn span(&self, py: f32, dx: f32) -> Option<(i32, i32)> {
        let (mut lo, mut hi) = (self.x_lo as f32, self.x_hi as f32);
        for k in 0..3 {
            let dy = py - self.y[k];
            match self.side[k] {
                1 => hi = hi.min(self.x[k] + self.slope[k] * dy + EDGE_EPS - dx),
                -1 => lo = lo.max(self.x[k] + self.slope[k] * dy - EDGE_EPS - dx),
                _ => {
                    if self.flat[k] * dy < 0.0 {
                        return None;
                    }
                }
            }
        }
        let (a, b) = (ceil_i(lo), floor_i(hi));
        (a <= b).then_some((a, b))
    }
}

/// Moves the visible chunks' triangles to the optical frame, clips them at the near plane
/// and projects them, keeping those that may cover a sample within `reach` pixels of a
/// pixel centre; the list is in chunk order (deterministic).
pub(crate) fn project_all(
    chunks: &Chunks,
    visible: &[Range<u32>],
    view: &View,
    reach: f32,
) -> Vec<ScreenTri> {
    let per_chunk: Vec<Vec<ScreenTri>> = visible
        .par_iter()
        .map(|range| {
            let mut out = Vec::with_capacity(range.len());
            for id in range.clone() {
                let t = &chunks.tris[id as usize];
                project(view, t.p.map(|p| view.to_optical(&p)), id, reach, &mut out);
            }
            out
        })
        .collect();
    per_chunk.concat()
}

fn project(view: &View, c: [[f32; 3]; 3], id: u32, reach: f32, out: &mut Vec<ScreenTri>) {
    let inside = c.map(|p| p[2] >= NEAR_M);
    let n_in = inside.iter().filter(|&&b| b).count();
    if n_in == 0 || c.iter().all(|p| p[2] > view.cull_beyond) {
        return;
    }
    // Quick reject: all corners beyond one side plane.
    let (l, r) = (-view.cx / view.fx, (view.width as f32 - view.cx) / view.fx);
    let (t, b) = (-view.cy / view.fy, (view.height as f32 - view.cy) / view.fy);
    if c.iter().all(|p| p[0] < l * p[2]) || c.iter().all(|p| p[0] > r * p[2]) {
        return;
    }
    if c.iter().all(|p| p[1] < t * p[2]) || c.iter().all(|p| p[1] > b * p[2]) {
        return;
    }
    let emit = |poly: &[[f32; 3]], out: &mut Vec<ScreenTri>| {
        // At most four corners (a triangle clipped by one plane): no allocation.
        let mut s = [(0.0f32, 0.0f32, 0.0f32); 4];
        for (s, p) in s.iter_mut().zip(poly) {
            let iz = 1.0 / p[2];
            *s = (
                view.fx * p[0] * iz + view.cx,
                view.fy * p[1] * iz + view.cy,
                iz,
            );
        }
        for k in 1..poly.len() - 1 {
            let v = [s[0], s[k], s[k + 1]];
            if let Some(tri) = ScreenTri::new(
                v.map(|p| p.0),
                v.map(|p| p.1),
                v.map(|p| p.2),
                id,
                (view.width, view.height),
                reach,
            ) {
                out.push(tri);
            }
        }
    };
    if n_in == 3 {
        emit(&c, out);
        return;
    }
    // Sutherland-Hodgman against z = NEAR.
    let mut poly = [[0.0f32; 3]; 4];
    let mut len = 0;
    for k in 0..3 {
        let (a, b) = (c[k], c[(k + 1) % 3]);
        if inside[k] {
            poly[len] = a;
            len += 1;
        }
        if inside[k] != inside[(k + 1) % 3] {
            let f = (NEAR_M - a[2]) / (b[2] - a[2]);
            poly[len] = [a[0] + f * (b[0] - a[0]), a[1] + f * (b[1] - a[1]), NEAR_M];
            len += 1;
        }
    }
    emit(&poly[..len], out);
}

/// For every band of `band_rows` rows, the indices of the triangles overlapping it.
pub(crate) fn bin_by_band(tris: &[ScreenTri], height: usize, band_rows: usize) -> Vec<Vec<u32>> {
    let mut bins = vec![Vec::new(); height.div_ceil(band_rows)];
    for (i, t) in tris.iter().enumerate() {
        let bands = (t.y_lo as usize / band_rows)..=(t.y_hi as usize / band_rows);
        for bin in &mut bins[bands] {
            bin.push(i as u32);
        }
    }
    bins
}

/// Draws the listed triangles into one band (pixel rows `first_row..`) of a `width`-wide
/// buffer with one sample per offset of `pattern`, laid out `[row][sample][column]` (the
/// single-sample renderer and the shadow map; see [`rasterize_band_ms`] for more samples).
pub(crate) fn rasterize_band(
    tris: &[ScreenTri],
    list: &[u32],
    first_row: usize,
    (width, pattern): (usize, &[[f32; 2]]),
    q_buf: &mut [f32],
    id_buf: &mut [u32],
) {
    let n = pattern.len();
    let rows = q_buf.len() / (width * n);
    let (y0, y1) = (first_row as i32, (first_row + rows) as i32 - 1);
    for &i in list {
        let t = &tris[i as usize];
        for py in t.y_lo.max(y0)..=t.y_hi.min(y1) {
            for (s, &[dx, dy]) in pattern.iter().enumerate() {
                let fy = py as f32 + dy;
                let Some((a, b)) = t.span(fy, dx) else {
                    continue;
                };
                let row = ((py - y0) as usize * n + s) * width;
                let span = row + a as usize..=row + b as usize;
                let q_row = t.q0 + t.qy * (fy - t.y[0]);
                // Depth test written as selects, not a branch: where surfaces overlap its
                // outcome is unpredictable.
                for ((px, qb), ib) in (a..=b).zip(&mut q_buf[span.clone()]).zip(&mut id_buf[span]) {
                    let q = q_row + t.qx * ((px as f32 + dx) - t.x[0]);
                    let nearer = q > *qb || (q == *qb && t.id < *ib);
                    *qb = if nearer { q } else { *qb };
                    *ib = if nearer { t.id } else { *ib };
                }
            }
        }
    }
}

/// Offset that makes span bounds positive before truncation (a raster narrower than this).
const OFFSET: i32 = 1024;
const OFFSET_F: f32 = OFFSET as f32;

/// [`rasterize_band`] for `N` samples a pixel at the offsets `pattern`, laid out
/// `[row][column][sample]`: the samples of a pixel are tested together.
pub(crate) fn rasterize_band_ms<const N: usize>(
    tris: &[ScreenTri],
    list: &[u32],
    first_row: usize,
    (width, pattern): (usize, &[[f32; 2]; N]),
    q_buf: &mut [f32],
    id_buf: &mut [u32],
) {
    const { assert!(N % 4 == 0, "whole vectors of four samples") };
    let rows = q_buf.len() / (width * N);
    let (y0, y1) = (first_row as i32, (first_row + rows) as i32 - 1);
    let dx = pattern.map(|o| o[0]);
    let dy = pattern.map(|o| o[1]);
    for &i in list {
        let t = &tris[i as usize];
        // The edges bounding the span on the left and on the right as (x, y, slope), two
        // slots each; an unused slot never binds.
        let mut left = [[-1e30f32, 0.0, 0.0]; 2];
        let mut right = [[1e30f32, 0.0, 0.0]; 2];
        let (mut nl, mut nr) = (0, 0);
        for k in 0..3 {
            let e = [t.x[k], t.y[k], t.slope[k]];
            match t.side[k] {
                -1 => {
                    left[nl] = e;
                    nl += 1;
                }
                1 => {
                    right[nr] = e;
                    nr += 1;
                }
                // A horizontal edge bounds the triangle's rows (below).
                _ => {}
            }
        }
        let y_min = t.y[0].min(t.y[1]).min(t.y[2]);
        let y_max = t.y[0].max(t.y[1]).max(t.y[2]);
        // Four samples at a time, lane by lane the scalar operations (`F4`).
        let edge = |e: [f32; 3]| e.map(F4::splat);
        let (left, right) = (left.map(edge), right.map(edge));
        let (x_lo, x_hi) = (t.x_lo as f32, t.x_hi as f32);
        let (lo_min, lo_max) = (F4::splat(x_lo), F4::splat(x_hi + 1.0));
        let (hi_min, hi_max) = (F4::splat(x_lo - 1.0), F4::splat(x_hi));
        let (y_min, y_max) = (F4::splat(y_min), F4::splat(y_max));
        let (eps, offset, none) = (
            F4::splat(EDGE_EPS),
            F4::splat(OFFSET_F),
            F4::splat(f32::NEG_INFINITY),
        );
        let (qy, y0_t) = (F4::splat(t.qy), F4::splat(t.y[0]));
        // 1 / z at sample `s` of column `px` on this row: `q_row[s] + qx px`.
        let q_col = dx.map(|dx| t.q0 + t.qx * (dx - t.x[0]));
        for py in t.y_lo.max(y0)..=t.y_hi.min(y1) {
            // Sample `s` covers column `px` when `ceil(lo) <= px <= floor(hi)`, the ceiling
            // and the floor being truncations of `OFFSET_F - lo` and `hi + OFFSET_F`
            // (positive: the bounds are clamped into the raster, so the offset costs 6e-5 px
            // of precision, under EDGE_EPS). For positive `y` and an integer `k`,
            // `trunc(y) >= k` exactly when `y >= k`, so the test is two float comparisons
            // per sample, `y_lo >= OFFSET - px` and `y_hi >= px + OFFSET`, with the same
            // outcome as with integers, and no conversion per sample (branch-free: the lanes
            // run as one vector). A sample row outside the triangle gets -inf: never covered.
            let (mut y_lo, mut y_hi, mut q_row) = ([0.0f32; N], [0.0f32; N], [0.0f32; N]);
            // The columns from the smallest ceiling to the largest floor (a NaN bound, from
            // a degenerate edge, covers nothing, as its comparisons fail).
            let (mut max_lo, mut max_hi) = (f32::NEG_INFINITY, f32::NEG_INFINITY);
            let py_f = F4::splat(py as f32);
            for c in (0..N).step_by(4) {
                let lanes = |a: &[f32; N]| F4::new([a[c], a[c + 1], a[c + 2], a[c + 3]]);
                let fy = py_f + lanes(&dy);
                let at = |e: &[F4; 3]| e[0] + e[2] * (fy - e[1]);
                let lo = at(&left[0]).max(at(&left[1])) - eps - lanes(&dx);
                let hi = at(&right[0]).min(at(&right[1])) + eps - lanes(&dx);
                let lo = lo.clamp(lo_min, lo_max);
                let hi = hi.clamp(hi_min, hi_max);
                let rows_in = fy.ge(y_min) & fy.le(y_max);
                let lo = F4::select(rows_in, offset - lo, none);
                let hi = F4::select(rows_in, hi + offset, none);
                max_lo = max_lo.max(lo.max_lane());
                max_hi = max_hi.max(hi.max_lane());
                y_lo[c..c + 4].copy_from_slice(&lo.to_array());
                y_hi[c..c + 4].copy_from_slice(&hi.to_array());
                let q = lanes(&q_col) + qy * (fy - y0_t);
                q_row[c..c + 4].copy_from_slice(&q.to_array());
            }
            if !(max_lo > 0.0 && max_hi > 0.0) {
                continue;
            }
            let first = OFFSET - max_lo as i32;
            let last = max_hi as i32 - OFFSET;
            if first > last {
                continue;
            }
            let row = (py - y0) as usize * width;
            let span = (row + first as usize) * N..(row + last as usize + 1) * N;
            for ((px, qb), ib) in (first..=last)
                .zip(q_buf[span.clone()].chunks_exact_mut(N))
                .zip(id_buf[span].chunks_exact_mut(N))
            {
                let fx = px as f32;
                // Exact: small integers.
                let (from_left, from_right) = ((OFFSET - px) as f32, (px + OFFSET) as f32);
                let (old_q, old_id): ([f32; N], [u32; N]) = (
                    (&*qb).try_into().expect("N samples"),
                    (&*ib).try_into().expect("N samples"),
                );
                let (mut new_q, mut new_id) = (old_q, old_id);
                // Lane by lane, as selects: one vector operation per step.
                for s in 0..N {
                    let covered = (y_lo[s] >= from_left) & (y_hi[s] >= from_right);
                    let q = q_row[s] + t.qx * fx;
                    let nearer =
                        covered & ((q > old_q[s]) | ((q == old_q[s]) & (t.id < old_id[s])));
                    new_q[s] = if nearer { q } else { old_q[s] };
                    new_id[s] = if nearer { t.id } else { old_id[s] };
                }
                qb.copy_from_slice(&new_q);
                ib.copy_from_slice(&new_id);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};

    /// The vector multisample rasterizer covers the same samples as the scanline one run
    /// once per sample row, on random triangles of every size overlapping in depth.
    #[test]
    fn multisample_rasterizer_agrees_with_the_scanline_one() {
        let (w, h) = (64usize, 16usize);
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(3);
        let mut tris = Vec::new();
        for id in 0..400u32 {
            let size = [0.7f32, 3.0, 20.0, 200.0, 1e5][id as usize % 5];
            let (cx, cy) = (
                rng.random_range(-5.0..70.0f32),
                rng.random_range(-5.0..20.0f32),
            );
            let x = [0; 3].map(|_| cx + rng.random_range(-size..size));
            let mut y = [0; 3].map(|_| cy + rng.random_range(-size..size));
            if id % 3 == 0 {
                // A horizontal edge, on a sample row or between.
                y[1] = if id % 2 == 0 {
                    y[0]
                } else {
                    y[0].round() - 0.125
                };
                y[0] = y[1];
            }
            let q = [0; 3].map(|_| rng.random_range(0.1..1.0f32));
            if let Some(t) = ScreenTri::new(x, y, q, id, (w, h), reach(&SAMPLES_4)) {
                tris.push(t);
            }
        }
        let list: Vec<u32> = (0..tris.len() as u32).collect();
        let (mut q1, mut id1) = (vec![0.0f32; 4 * w * h], vec![u32::MAX; 4 * w * h]);
        let (mut q2, mut id2) = (q1.clone(), id1.clone());
        rasterize_band(&tris, &list, 0, (w, &SAMPLES_4), &mut q1, &mut id1);
        rasterize_band_ms(&tris, &list, 0, (w, &SAMPLES_4), &mut q2, &mut id2);
        let mut differ = 0;
        for v in 0..h {
            for u in 0..w {
                for s in 0..4 {
                    let (a, b) = (id1[(v * 4 + s) * w + u], id2[(v * w + u) * 4 + s]);
                    if a != b {
                        differ += 1;
                        eprintln!("({u}, {v}) sample {s}: scanline {a}, vector {b}");
                    }
                }
            }
        }
        assert_eq!(differ, 0, "expected the same triangle in every sample");
    }
}
