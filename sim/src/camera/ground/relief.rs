//! The ground's relief under the camera's sun, baked once per camera: for every texel of a
//! patch, Lambert on the height field's normal and a shadow test by marching towards the
//! sun over the height field (the texel-by-texel form of horizon mapping, Max 1988,
//! "Horizon mapping: shadows for bump-mapped surfaces").

use rayon::prelude::*;

use super::{AXIS, MAX_RELIEF, SIDE};
use crate::camera::shading::Light;
use crate::camera::texture::floor;

/// Furthest a shadow is followed over the height field, texels.
const MAX_MARCH: usize = 32;

/// Direct sunlight on every texel of the height field (texels high) relative to a flat
/// surface: Lambert on the field's normal, times 0 where a lump between it and the sun
/// rises above the sun's ray (softened over half a texel).
pub(super) fn relief(height: &[f32], light: &Light) -> Vec<f32> {
    let n = SIDE;
    let l = light.sun;
    // The sun in the patch's frame.
    let (lu, lv) = (
        AXIS[0] * l[0] + AXIS[1] * l[1],
        AXIS[0] * l[1] - AXIS[1] * l[0],
    );
    let horizontal = (lu * lu + lv * lv).sqrt();
    let flat = l[2].max(0.05);
    let top = height.iter().copied().fold(f32::NEG_INFINITY, f32::max);
    let at = |i: isize, j: isize| {
        // Two's complement: masking wraps negative indices too.
        height[(j as usize & (n - 1)) * n + (i as usize & (n - 1))]
    };
    (0..n * n)
        .into_par_iter()
        .with_min_len(n)
        .map(|k| {
            let (i, j) = ((k % n) as isize, (k / n) as isize);
            let h = height[k];
            let (gx, gy) = (
                0.5 * (at(i + 1, j) - at(i - 1, j)),
                0.5 * (at(i, j + 1) - at(i, j - 1)),
            );
            let ndl = (l[2] - gx * lu - gy * lv) / (1.0 + gx * gx + gy * gy).sqrt();
            if ndl <= 0.0 {
                return 0.0;
            }
            let mut lit = 1.0f32;
            if horizontal > 1e-3 {
                // The sun's ray rises `rise` texels per texel travelled towards it.
                let rise = l[2] / horizontal;
                let (du, dv) = (lu / horizontal, lv / horizontal);
                let (mut pu, mut pv) = (i as f32 + 0.5, j as f32 + 0.5);
                for s in 1..=MAX_MARCH {
                    let ray = h + s as f32 * rise;
                    if ray > top {
                        break;
                    }
                    pu += du;
                    pv += dv;
                    let above = at(floor(pu).1 as isize, floor(pv).1 as isize) - ray;
                    lit = lit.min((0.5 - above * 2.0).clamp(0.0, 1.0));
                    if lit == 0.0 {
                        break;
                    }
                }
            }
            (ndl * lit / flat).min(MAX_RELIEF)
        })
        .collect()
}
