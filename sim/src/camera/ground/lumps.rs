//! The tilled ground: fine soil with grit, and lumps of three sizes (big and medium clods,
//! crumbs). A lump is the cell of a jittered-grid Voronoi diagram cut by a disc, so it is
//! angular where it meets a neighbour and rounded elsewhere, with a V-shaped crack between
//! neighbours (Worley's F2 − F1); clods are broken into facets by a finer Voronoi grid.
//! Lumps see a plane warped by noise, so their edges are wavy; how cloddy (and how pale)
//! the ground is varies over half a metre.

use rayon::prelude::*;

use super::SIDE;
use super::grid::{Grid, noise, splat};
use super::tile::{Texel, inside, scale};
use crate::camera::texture::{hash, lerp, smooth};

/// Fine soil between the lumps: darker, moister brown.
const FINE: [f32; 3] = [0.27, 0.21, 0.17];
/// Lumps: drier and paler.
const CLOD: [f32; 3] = [0.64, 0.53, 0.41];
const LIGHT_GRIT: [f32; 3] = [0.70, 0.66, 0.58];
const DARK_GRIT: [f32; 3] = [0.22, 0.18, 0.15];
/// Largest displacement of the plane the lumps see, texels.
const WARP: f32 = 3.5;

/// One size of lump.
#[derive(Debug)]
struct Kind {
    grid: Grid,
    /// Share of the cells holding a lump where the ground is least and most cloddy.
    presence: [f32; 2],
    /// Radius range, fraction of the cell.
    radius: [f32; 2],
    /// Broken into facets.
    faceted: bool,
}

/// Height of a lump, fraction of its radius.
const HEIGHT: [f32; 2] = [0.5, 0.8];

/// How cloddy, and pale, the ground is around `(x, y)`, in [0, 1).
fn tone(x: f32, y: f32) -> f32 {
    noise(x, y, 128, 3)
}

/// Texel `(i, j)` of the bare ground: fine soil and grit.
pub(super) fn ground(i: usize, j: usize) -> Texel {
    let (x, y) = (i as f32 + 0.5, j as f32 + 0.5);
    let grain = hash(i as i32, j as i32, 1, 4) - 0.5;
    let mut t = Texel {
        h: 1.2 * (noise(x, y, 64, 5) - 0.5) + 0.4 * (noise(x, y, 8, 6) - 0.5),
        c: scale(FINE, 0.85 + 0.25 * tone(x, y) + 0.2 * grain),
    };
    let g = hash(i as i32, j as i32, 0, 8);
    if g < 0.05 {
        t.over(
            t.h + 0.3,
            if g < 0.03 { LIGHT_GRIT } else { DARK_GRIT },
            1.0,
        );
    }
    t
}

/// Puts the lumps over the ground, big ones first.
pub(super) fn lay(texels: &mut [Texel]) {
    let warp: Vec<[f32; 2]> = (0..SIDE * SIDE)
        .into_par_iter()
        .with_min_len(SIDE)
        .map(|k| {
            let (x, y) = ((k % SIDE) as f32 + 0.5, (k / SIDE) as f32 + 0.5);
            [1, 2].map(|salt| 2.0 * WARP * (noise(x, y, 8, salt) - 0.5))
        })
        .collect();
    let facets = Grid::new(8, 0.9, 108);
    let kind = |cell, salt, presence, radius, faceted| Kind {
        grid: Grid::new(cell, 0.9, salt),
        presence,
        radius,
        faceted,
    };
    let kinds = [
        kind(32, 101, [0.15, 0.65], [0.35, 0.6], true),
        kind(16, 107, [0.3, 0.6], [0.35, 0.6], true),
        kind(8, 102, [0.45, 0.45], [0.3, 0.55], false),
    ];
    for kind in &kinds {
        for (k, s) in kind.grid.sites.iter().enumerate() {
            let presence = lerp(kind.presence[0], kind.presence[1], tone(s.x, s.y));
            if s.r[0] >= presence {
                continue;
            }
            let r = kind.grid.cell * lerp(kind.radius[0], kind.radius[1], s.r[1]);
            let top = r * lerp(HEIGHT[0], HEIGHT[1], s.r[2]);
            let salt = 9 + (s.r[3] * 7.0) as u32;
            let neighbours = kind.grid.neighbours(k);
            splat(s.x, s.y, r + WARP + 1.0, |texel, dx, dy| {
                // The warped point, from the site.
                let (dx, dy) = (dx + warp[texel][0], dy + warp[texel][1]);
                let f1 = (dx * dx + dy * dy).sqrt();
                if f1 >= r {
                    return;
                }
                let f2 = neighbours
                    .iter()
                    .map(|n| ((dx - n[0]).powi(2) + (dy - n[1]).powi(2)).sqrt())
                    .fold(f32::INFINITY, f32::min);
                if f2 <= f1 {
                    // The neighbour's cell.
                    return;
                }
                let (x, y) = (s.x + dx, s.y + dy);
                // Rounder than a paraboloid, flatter than a hemisphere.
                let q = 1.0 - (f1 / r).powi(2);
                let dome = 0.5 * (q + q.sqrt());
                let crack = smooth(((f2 - f1) * 0.25).clamp(0.0, 1.0));
                let rough = noise(x, y, 4, salt) - 0.5;
                let mut h = (top * dome + 1.6 * rough) * crack;
                let mut c = scale(CLOD, 0.82 + 0.3 * s.r[4] + 0.15 * rough);
                if kind.faceted {
                    let (g1, _, facet, _) = facets.worley(x, y);
                    h -= 0.15 * g1 * crack;
                    c = scale(c, 0.94 + 0.12 * facet.r[0]);
                }
                texels[texel].over(h, c, inside(f1, r, 1.0));
            });
        }
    }
}
