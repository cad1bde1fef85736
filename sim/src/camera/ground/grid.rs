//! Periodic building blocks of the soil patch: jittered grids of feature sites (one site
//! per cell, as in Worley 1996, "A cellular texture basis function"), value noise, and
//! splatting a feature's footprint. Everything wraps with the patch's period, so the patch
//! tiles without seams; cells per side are powers of two, so wrapping is a mask.

use super::SIDE;
use crate::camera::texture::{floor, hash, lerp, smooth};

/// A grid cell's site: where its feature sits and the feature's random draws.
#[derive(Debug, Clone, Copy)]
pub(super) struct Site {
    /// Position in texels, within the patch.
    pub x: f32,
    pub y: f32,
    /// Uniform draws in [0, 1).
    pub r: [f32; 6],
}

/// `n x n` cells of `cell` texels over the patch, one site each.
#[derive(Debug)]
pub(super) struct Grid {
    pub cell: f32,
    per_cell: f32,
    n: i32,
    pub sites: Vec<Site>,
}

impl Grid {
    /// Sites at `jitter` (0: cell centres, 1: anywhere in the cell) from hashes salted
    /// with `salt`.
    pub fn new(cell: usize, jitter: f32, salt: u32) -> Self {
        let n = (SIDE / cell) as i32;
        let sites = (0..n * n)
            .map(|k| {
                let (i, j) = (k % n, k / n);
                let spread = |u: f32| 0.5 + (u - 0.5) * jitter;
                Site {
                    x: (i as f32 + spread(hash(i, j, 6, salt))) * cell as f32,
                    y: (j as f32 + spread(hash(i, j, 7, salt))) * cell as f32,
                    r: [0, 1, 2, 3, 4, 5].map(|m| hash(i, j, m, salt)),
                }
            })
            .collect();
        Self {
            cell: cell as f32,
            per_cell: 1.0 / cell as f32,
            n,
            sites,
        }
    }

    /// The sites of the eight cells around site `k`'s, as offsets from it (the copies
    /// next to it).
    pub fn neighbours(&self, k: usize) -> [[f32; 2]; 8] {
        let (ci, cj) = (k as i32 % self.n, k as i32 / self.n);
        let s = &self.sites[k];
        let mask = self.n - 1;
        let mut out = [[0.0; 2]; 8];
        let around = (-1..=1).flat_map(|dj| (-1..=1).map(move |di| (di, dj)));
        for ((di, dj), o) in around.filter(|&d| d != (0, 0)).zip(&mut out) {
            let (i, j) = (ci + di, cj + dj);
            let (wi, wj) = (i & mask, j & mask);
            let t = &self.sites[(wj * self.n + wi) as usize];
            *o = [
                t.x + (i - wi) as f32 * self.cell - s.x,
                t.y + (j - wj) as f32 * self.cell - s.y,
            ];
        }
        out
    }

    /// Worley's F1 and F2 at `(x, y)` (distances to the nearest and the second-nearest
    /// site, over the 3x3 cells around it), the nearest site and `(x, y)`'s offset from it.
    pub fn worley(&self, x: f32, y: f32) -> (f32, f32, &Site, [f32; 2]) {
        let (ci, cj) = (floor(x * self.per_cell).1, floor(y * self.per_cell).1);
        let mask = self.n - 1;
        // Squared distances; the roots of the two kept.
        let (mut d1, mut d2) = (f32::INFINITY, f32::INFINITY);
        let mut nearest = (&self.sites[0], [0.0; 2]);
        for j in cj - 1..=cj + 1 {
            // Masking wraps negative indices too; the site's copy next to the point is
            // a whole number of periods away.
            let wj = j & mask;
            let oy = y - (j - wj) as f32 * self.cell;
            for i in ci - 1..=ci + 1 {
                let wi = i & mask;
                let s = &self.sites[(wj * self.n + wi) as usize];
                let (dx, dy) = (x - (i - wi) as f32 * self.cell - s.x, oy - s.y);
                let d = dx * dx + dy * dy;
                if d < d1 {
                    d2 = d1;
                    d1 = d;
                    nearest = (s, [dx, dy]);
                } else if d < d2 {
                    d2 = d;
                }
            }
        }
        (d1.sqrt(), d2.sqrt(), nearest.0, nearest.1)
    }
}

/// Value noise in [0, 1) with lattice spacing `cell` texels.
pub(super) fn noise(x: f32, y: f32, cell: usize, salt: u32) -> f32 {
    let mask = (SIDE / cell) as i32 - 1;
    let (gx, gy) = (x / cell as f32, y / cell as f32);
    let ((xf, xi), (yf, yi)) = (floor(gx), floor(gy));
    let (fx, fy) = (smooth(gx - xf), smooth(gy - yf));
    let h = |i: i32, j: i32| hash(i & mask, j & mask, 0, salt);
    let a = lerp(h(xi, yi), h(xi + 1, yi), fx);
    let b = lerp(h(xi, yi + 1), h(xi + 1, yi + 1), fx);
    lerp(a, b, fy)
}

/// Calls `f(k, dx, dy)` for every texel `k` (row-major) whose centre lies within `reach`
/// (per axis) of `(cx, cy)`, with the offset of its centre from there, wrapping at the
/// patch's edges. Texels are visited row by row, so the order is fixed.
pub(super) fn splat(cx: f32, cy: f32, reach: f32, mut f: impl FnMut(usize, f32, f32)) {
    let mask = SIDE - 1;
    let (i0, i1) = (floor(cx - reach).1, floor(cx + reach).1);
    let (j0, j1) = (floor(cy - reach).1, floor(cy + reach).1);
    for j in j0..=j1 {
        let row = (j as usize & mask) * SIDE;
        let dy = j as f32 + 0.5 - cy;
        for i in i0..=i1 {
            f(row + (i as usize & mask), i as f32 + 0.5 - cx, dy);
        }
    }
}
