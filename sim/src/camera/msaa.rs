//! Multisample resolve: a pixel's colour from its visibility samples, each distinct
//! triangle among them shaded once (Akeley 1993, "RealityEngine graphics"; the MSAA of
//! every GPU since): at the centroid of the samples it covers, so that a triangle is never
//! shaded outside itself (OpenGL's `centroid` sampling), weighted by the share of the samples
//! it covers, and summed in linear light. A pixel whose samples all see one triangle is
//! shaded once at its centre, exactly as without anti-aliasing.
//!
//! Depth is not averaged. A time-of-flight pixel at an edge mixes the returns of both
//! surfaces into a range between them, or beyond (the Kinect v2's "flying pixels", which its
//! driver removes: libfreenect2's edge-aware filter); an average would invent exactly those
//! points, in space where there is nothing. The depth of a pixel is instead that of the
//! surface covering most of its samples (ties to the nearer), along the pixel's central ray
//! through that surface's plane: a point of a real surface, within half a pixel of where the
//! surface is seen, and the same depth the single-sample renderer gives wherever the
//! surface covers the pixel centre. Sky (no surface) wins only a majority: then the pixel
//! has no return (0). What the driver then drops at depth edges is
//! `depth_noise`'s edge dropout.

use super::shading::{Shaded, Shader};

/// The largest pattern (8 samples).
const MAX_SAMPLES: usize = 8;

/// The mean 1 / z of a pixel's samples `q` that all see one surface: the fallback depth
/// where its central ray grazes the surface's plane.
pub(crate) fn mean_q(q: &[f32]) -> f32 {
    q.iter().sum::<f32>() / q.len() as f32
}

/// The distinct surfaces among a pixel's samples, in sample order: id, samples covered,
/// sums of their offsets and of their 1 / z.
struct Groups {
    id: [u32; MAX_SAMPLES],
    count: [u32; MAX_SAMPLES],
    sum: [[f32; 3]; MAX_SAMPLES],
    len: usize,
}

impl Groups {
    fn of(pattern: &[[f32; 2]], ids: &[u32], q: &[f32]) -> Self {
        let mut g = Self {
            id: [u32::MAX; MAX_SAMPLES],
            count: [0; MAX_SAMPLES],
            sum: [[0.0; 3]; MAX_SAMPLES],
            len: 0,
        };
        for (s, (&sid, &[dx, dy])) in ids.iter().zip(pattern).enumerate() {
            let k = g.id[..g.len]
                .iter()
                .position(|&i| i == sid)
                .unwrap_or_else(|| {
                    g.id[g.len] = sid;
                    g.len += 1;
                    g.len - 1
                });
            g.count[k] += 1;
            g.sum[k] = [g.sum[k][0] + dx, g.sum[k][1] + dy, g.sum[k][2] + q[s]];
        }
        g
    }

    /// Group `k`'s centroid about the pixel centre `(x, y)` and its mean 1 / z.
    fn centroid(&self, k: usize, (x, y): (f32, f32)) -> ((f32, f32), f32) {
        let inv = 1.0 / self.count[k] as f32;
        let s = self.sum[k];
        ((x + s[0] * inv, y + s[1] * inv), s[2] * inv)
    }

    /// The majority: most samples, then nearest (largest mean 1 / z; sky's is 0), then the
    /// smaller id (the groups are in sample order, so only a strict win replaces).
    fn majority(&self) -> usize {
        let (mut best, mut best_key) = (0, (0u32, f32::NEG_INFINITY));
        for k in 0..self.len {
            let key = (self.count[k], self.centroid(k, (0.0, 0.0)).1);
            let wins = key.0 > best_key.0
                || (key.0 == best_key.0
                    && (key.1 > best_key.1 || (key.1 == best_key.1 && self.id[k] < self.id[best])));
            if k == 0 || wins {
                (best, best_key) = (k, key);
            }
        }
        best
    }
}

/// The pixel at column `u` of row `v` from its samples: `ids[s]` and `q[s]` (1 / z, 0 for
/// none) of the sample at offset `pattern[s]`.
pub(crate) fn resolve(
    shader: &Shader<'_>,
    pattern: &[[f32; 2]],
    (x, y): (f32, f32),
    ids: &[u32],
    q: &[f32],
) -> Shaded {
    let n = pattern.len();
    let first = ids[0];
    if ids[1..n].iter().all(|&id| id == first) {
        // One triangle (or sky) in every sample: shaded at the centre, the offsets' mean.
        return shader.shade(x, y, first, mean_q(&q[..n]));
    }
    let groups = Groups::of(pattern, ids, q);
    let weight = 1.0 / n as f32;
    let mut rgb = [0.0f32; 3];
    let best = groups.majority();
    let mut majority = None;
    for g in 0..groups.len {
        let (centroid, mean_q) = groups.centroid(g, (x, y));
        let s = shader.shade(centroid.0, centroid.1, groups.id[g], mean_q);
        let w = groups.count[g] as f32 * weight;
        for (acc, c) in rgb.iter_mut().zip(s.rgb) {
            *acc += c * w;
        }
        if g == best {
            majority = Some(s);
        }
    }
    let majority = majority.expect("the majority is one of the groups");
    let (depth, cos_incidence) = if groups.id[best] == u32::MAX {
        (0.0, 0.0)
    } else {
        shader.depth_at(
            x,
            y,
            groups.id[best],
            (majority.depth, majority.cos_incidence),
        )
    };
    Shaded {
        rgb,
        depth,
        cos_incidence,
    }
}

/// The depth and incidence cosine [`resolve`] gives the pixel, bit for bit, without
/// shading any colour: the majority surface (most samples, then nearest, then the smaller
/// id) along the pixel's central ray, its plane's depth at the majority's centroid where
/// that ray grazes it. For a depth camera's pass.
pub(crate) fn resolve_depth(
    shader: &Shader<'_>,
    pattern: &[[f32; 2]],
    (x, y): (f32, f32),
    ids: &[u32],
    q: &[f32],
) -> (f32, f32) {
    let n = pattern.len();
    let first = ids[0];
    if ids[1..n].iter().all(|&id| id == first) {
        return shader.depth_only(x, y, first, mean_q(&q[..n]));
    }
    let groups = Groups::of(pattern, ids, q);
    let best = groups.majority();
    if groups.id[best] == u32::MAX {
        return (0.0, 0.0);
    }
    let (centroid, mean_q) = groups.centroid(best, (x, y));
    let majority = shader.depth_only(centroid.0, centroid.1, groups.id[best], mean_q);
    shader.depth_at(x, y, groups.id[best], majority)
}

#[cfg(test)]
mod tests {
    use super::super::raster::{SAMPLES_4, SAMPLES_8};

    #[test]
    fn patterns_are_centred_with_a_row_and_a_column_per_sample() {
        for pattern in [&SAMPLES_4[..], &SAMPLES_8[..]] {
            let (sx, sy) = pattern
                .iter()
                .fold((0.0, 0.0), |(x, y), o| (x + o[0], y + o[1]));
            assert_eq!((sx, sy), (0.0, 0.0), "expected offsets summing to zero");
            for (i, a) in pattern.iter().enumerate() {
                assert!(
                    a[0].abs() < 0.5 && a[1].abs() < 0.5,
                    "{a:?} outside the pixel"
                );
                for b in &pattern[i + 1..] {
                    assert!(
                        a[0] != b[0] && a[1] != b[1],
                        "expected {a:?} and {b:?} on distinct rows and columns"
                    );
                }
            }
        }
    }
}
