//! The grass patch: tufts of blades over dark ground. A tuft is a cell of a jittered-grid
//! Voronoi diagram (Worley 1996) seen from above: blades radiate from its site, each of its
//! own length and shade, lighter towards the tip, with gaps between them. Tufts are green or
//! straw-coloured by patches over a metre or so, and gather in tussocks with bare gaps
//! between them; a few flowers dot the grass.

use rayon::prelude::*;

use super::SIDE;
use super::grid::{Grid, noise};
use super::tile::{Texel, Tile, inside, scale};
use crate::camera::texture::{hash, lerp};

const DIRT: [f32; 3] = [0.24, 0.21, 0.14];
const GREEN: [f32; 3] = [0.28, 0.44, 0.14];
const DRY: [f32; 3] = [0.64, 0.58, 0.34];
const DAISY: [f32; 3] = [0.90, 0.90, 0.85];
const BUTTERCUP: [f32; 3] = [0.90, 0.78, 0.20];
/// Blades around a tuft.
const BLADES: f32 = 22.0;

pub(super) fn generate() -> Tile {
    let tufts = Grid::new(16, 0.7, 201);
    let tussocks = Grid::new(64, 0.5, 206);
    let texels: Vec<Texel> = (0..SIDE * SIDE)
        .into_par_iter()
        .with_min_len(SIDE)
        .map(|k| texel(&tufts, &tussocks, k % SIDE, k / SIDE))
        .collect();
    Tile::finish(&texels, 0.12, 0.35, 1.15)
}

fn texel(tufts: &Grid, tussocks: &Grid, i: usize, j: usize) -> Texel {
    let (x, y) = (i as f32 + 0.5, j as f32 + 0.5);
    // Tussocks: the tufts stand higher and denser towards their middle.
    let (f1, _, s, _) = tussocks.worley(x, y);
    let mound = (1.0 - f1 / (tussocks.cell * (0.6 + 0.3 * s.r[0]))).max(0.0);
    let mut t = Texel {
        h: 10.0 * mound * mound,
        c: scale(DIRT, 0.8 + 0.4 * noise(x, y, 4, 202)),
    };
    let base = t.h;
    let (f1, _, s, [dx, dy]) = tufts.worley(x, y);
    let r = tufts.cell * (0.6 + 0.4 * s.r[1]);
    if f1 < r {
        // Which blade: the pseudo-angle around the site, in turns (no libm call).
        let a = if f1 > 0.0 { diamond_angle(dx, dy) } else { 0.0 };
        let b = a * BLADES + 7.0 * s.r[2];
        let blade = b as i32;
        let across = (b - blade as f32 - 0.5).abs() * 2.0;
        let draw = hash(blade, (s.r[3] * 65536.0) as i32, 0, 203);
        let length = r * (0.55 + 0.45 * draw);
        let along = f1 / length;
        if along < 1.0 {
            // Dry or green by patches, a tuft at a time.
            let dry = (noise(s.x, s.y, 128, 204) - 0.45) * 3.0 + (s.r[4] - 0.5);
            let shade = 0.75 + 0.35 * hash(blade, (s.r[5] * 65536.0) as i32, 1, 203);
            let c = scale(
                lerp3(GREEN, DRY, dry.clamp(0.0, 1.0)),
                shade * (0.8 + 0.35 * along),
            );
            // Blades arch up from the site and taper.
            let h = base + (0.4 + 0.6 * mound) * r * (1.0 - along * along) * (1.0 - 0.6 * across);
            t.over(h, c, inside(across, 0.75, 0.3) * (0.5 + mound).min(1.0));
        }
    }
    let g = hash(i as i32, j as i32, 0, 205);
    if g < 0.004 {
        t.over(t.h + 1.0, if g < 0.0025 { DAISY } else { BUTTERCUP }, 1.0);
    }
    t
}

/// The angle of `(dx, dy)` in turns, [0, 1), monotonic in the true angle but not linear in
/// it: the position along the unit diamond |x| + |y| = 1.
fn diamond_angle(dx: f32, dy: f32) -> f32 {
    let p = if dy >= 0.0 {
        if dx >= 0.0 {
            dy / (dx + dy)
        } else {
            1.0 - dx / (-dx + dy)
        }
    } else if dx < 0.0 {
        2.0 - dy / (-dx - dy)
    } else {
        3.0 + dx / (dx - dy)
    };
    p * 0.25
}

fn lerp3(a: [f32; 3], b: [f32; 3], t: f32) -> [f32; 3] {
    [0, 1, 2].map(|k| lerp(a[k], b[k], t))
}
