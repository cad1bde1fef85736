//! What lies on the tilled ground, splatted over it: angular stones (limestone, sandstone
//! and darker schist; convex hexagons with faces at irregular distances, in an ellipse's frame), round
//! gravel, dry grass straws and pieces of pruned cane with light cut ends. Each kind sits on
//! its own jittered grid; a share of the cells holds one.

use super::grid::{Grid, Site, noise, splat};
use super::tile::{Texel, inside, scale};
use crate::camera::texture::hash;

const LIMESTONE: [f32; 3] = [0.80, 0.77, 0.70];
const SANDSTONE: [f32; 3] = [0.64, 0.54, 0.42];
const SCHIST: [f32; 3] = [0.42, 0.40, 0.38];
const STRAW: [f32; 3] = [0.82, 0.74, 0.52];
const BARK: [f32; 3] = [0.34, 0.27, 0.21];
const CUT_WOOD: [f32; 3] = [0.72, 0.63, 0.46];

/// Unit normals of a regular hexagon's faces.
const HEXAGON: [[f32; 2]; 6] = [
    [1.0, 0.0],
    [0.5, 0.866_025_4],
    [-0.5, 0.866_025_4],
    [-1.0, 0.0],
    [-0.5, -0.866_025_4],
    [0.5, -0.866_025_4],
];

/// Puts every kind of debris over the ground, in a fixed order.
pub(super) fn scatter(texels: &mut [Texel]) {
    for s in &Grid::new(32, 0.6, 103).sites {
        stone(texels, s);
    }
    for s in &Grid::new(16, 0.8, 104).sites {
        gravel(texels, s);
    }
    for s in &Grid::new(32, 0.8, 105).sites {
        // Up to two straws per cell, either side of the site.
        for (k, presence, offset) in [(0, 0.5, -9.0), (3, 0.25, 9.0)] {
            if s.r[k] < presence {
                straw(texels, s.x + offset, s.y, [s.r[k + 1], s.r[k + 2], s.r[5]]);
            }
        }
    }
    for s in &Grid::new(64, 0.8, 106).sites {
        cane(texels, s);
    }
}

fn stone(texels: &mut [Texel], s: &Site) {
    if s.r[0] >= 0.65 {
        return;
    }
    // Semi-axes and orientation.
    let a = 3.5 + 9.0 * s.r[1] * s.r[1];
    let b = a * (0.6 + 0.4 * s.r[2]);
    let [ux, uy] = direction(s.r[3]);
    let reach: [f32; 6] = std::array::from_fn(|k| {
        1.0 / (0.85 + 0.3 * hash(k as i32, 0, 0, (s.r[5] * 65536.0) as u32))
    });
    let base = match s.r[4] {
        u if u < 0.45 => LIMESTONE,
        u if u < 0.75 => SANDSTONE,
        _ => SCHIST,
    };
    splat(s.x, s.y, 1.3 * a + 1.0, |k, dx, dy| {
        let t = &mut texels[k];
        let (p, q) = ((dx * ux + dy * uy) / a, (dy * ux - dx * uy) / b);
        // Six faces at irregular distances: d < 1 inside.
        let d = (0..6).fold(0.0f32, |d, k| {
            d.max((p * HEXAGON[k][0] + q * HEXAGON[k][1]) * reach[k])
        });
        let cover = inside(d, 1.0, 1.2 / b);
        if cover > 0.0 {
            let h = 0.8 * b * (1.0 - d * d).max(0.0).sqrt() - 0.3 * b * s.r[4];
            let mottle = noise(s.x + dx, s.y + dy, 2, 11) - 0.5;
            let c = scale(base, 0.8 + 0.35 * s.r[5] + 0.15 * mottle);
            t.over(0.4 * t.h.max(0.0) + h.max(0.3), c, cover);
        }
    });
}

fn gravel(texels: &mut [Texel], s: &Site) {
    if s.r[0] >= 0.5 {
        return;
    }
    let r = 1.2 + 2.3 * s.r[1];
    let c = scale(
        if s.r[2] < 0.6 { LIMESTONE } else { SCHIST },
        0.8 + 0.3 * s.r[3],
    );
    splat(s.x, s.y, r + 1.0, |k, dx, dy| {
        let t = &mut texels[k];
        let d = (dx * dx + dy * dy).sqrt();
        let cover = inside(d, r, 1.0);
        if cover > 0.0 {
            let h = 0.7 * r * (1.0 - (d / r).powi(2)).max(0.0).sqrt();
            t.over(t.h + h, c, cover);
        }
    });
}

/// A straw centred at `(x, y)` from three draws (length, direction, tone), lying on
/// whatever is below it.
fn straw(texels: &mut [Texel], x: f32, y: f32, r: [f32; 3]) {
    let half = 3.0 + 9.0 * r[0];
    let [ux, uy] = direction(r[1]);
    let c = scale(STRAW, 0.8 + 0.3 * r[2]);
    splat(x, y, half + 1.0, |k, dx, dy| {
        let t = &mut texels[k];
        let (d, _) = segment(dx, dy, ux, uy, half);
        let cover = inside(d, 0.55, 0.7);
        if cover > 0.0 {
            t.over(t.h + 0.5, c, cover);
        }
    });
}

fn cane(texels: &mut [Texel], s: &Site) {
    if s.r[0] >= 0.12 {
        return;
    }
    let half = 12.0 + 40.0 * s.r[1];
    let w = 1.4 + 0.8 * s.r[2];
    let [ux, uy] = direction(s.r[3]);
    splat(s.x, s.y, half + w + 1.0, |k, dx, dy| {
        let t = &mut texels[k];
        let (d, along) = segment(dx, dy, ux, uy, half);
        let cover = inside(d, w, 0.8);
        if cover > 0.0 {
            let round = (1.0 - (d / w).powi(2)).max(0.0).sqrt();
            let c = if half - along.abs() < 0.8 {
                CUT_WOOD
            } else {
                scale(BARK, 0.8 + 0.4 * noise(along * 0.5, d * 3.0, 4, 12))
            };
            t.over(t.h.max(0.0) + 2.0 * w * round, c, cover);
        }
    });
}

/// A unit vector from a draw in [0, 1): a rational parametrisation of the quarter circle,
/// turned into the quadrant (no libm call).
fn direction(u: f32) -> [f32; 2] {
    let v = u * 4.0;
    let t = v - (v as i32) as f32;
    let (c, s) = ((1.0 - t * t) / (1.0 + t * t), 2.0 * t / (1.0 + t * t));
    match v as i32 {
        0 => [c, s],
        1 => [-s, c],
        2 => [-c, -s],
        _ => [s, -c],
    }
}

/// Distance from `(px, py)` to the segment of half-length `half` along the unit `(ux, uy)`
/// through the origin, and the position along it (clamped).
fn segment(px: f32, py: f32, ux: f32, uy: f32, half: f32) -> (f32, f32) {
    let along = (px * ux + py * uy).clamp(-half, half);
    let (ex, ey) = (px - along * ux, py - along * uy);
    ((ex * ex + ey * ey).sqrt(), along)
}
