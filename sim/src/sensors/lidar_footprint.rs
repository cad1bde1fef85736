//! Beam divergence and mixed pixels: a lidar's beam is a narrow cone, not a ray, and its
//! footprint grows with range. Where the footprint straddles an edge (a post, a leaf, a wire
//! in front of the row behind) the receiver sees light from two surfaces at once; when
//! their ranges are too close for the receiver to part the two echoes it reports one point
//! between them, on no surface: a *mixed pixel* (Tuley, Vandapel and Hebert, "Analysis and
//! removal of artifacts in 3-D LADAR data", ICRA 2005). When they are far enough apart it
//! reports one of the echoes, as its return mode says (VLP-16 User Manual 63-9243 Rev D,
//! §6.2: strongest, last, or both).
//!
//! The model: the footprint, `divergence` wide (full angles, horizontal along the scan and
//! vertical), is sampled by a 3 × 3 grid of sub-rays at the centres of its thirds, each
//! carrying a ninth of the pulse (a flat-topped beam). A sub-ray that meets a surface at range
//! `t` returns energy `ρ cos θ / t²` (the material's near-infrared reflectivity, Lambert,
//! an extended target). Sub-ray hits closer in range than `echo_separation` merge into one
//! echo at their energy-weighted mean range; the sensor reports the strongest echo (the
//! most energy) or the last (the farthest). Its intensity is `255 Σ ρ cos θ / 9` over the
//! echo's sub-rays: a whole footprint on one surface gives the thin ray's `255 ρ cos θ`.
//!
//! Cost: the sub-rays are cast only for beams next to a range discontinuity in the scan
//! (see [`straddles`]); elsewhere the footprint lies on one surface and the central ray's
//! hit is the return. Objects thinner than the column spacing that the central rays miss
//! altogether (a wire between two columns) stay unseen, as with thin rays.

use nalgebra::{Point3, Vector3};

use crate::raycast::{Hit, RayCaster};
use crate::world::Mesh;

/// Which echo a single-return lidar reports when the footprint gives more than one.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Deserialize, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum ReturnMode {
    /// The echo with the most energy.
    #[default]
    Strongest,
    /// The farthest echo.
    Last,
}

/// The beam's footprint and what the receiver makes of it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Footprint {
    /// Full divergence angles, horizontal (along the scan) and vertical, rad.
    pub divergence_rad: [f32; 2],
    /// Echoes closer in range than this merge into one, m.
    pub echo_separation_m: f32,
    pub mode: ReturnMode,
}

/// A beam's return: its range along the beam and its intensity, 0-255.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Return {
    pub range_m: f32,
    pub intensity: f32,
}

/// Sub-ray offsets in half widths of the footprint: the centres of its thirds.
const OFFSETS: [f32; 3] = [-2.0 / 3.0, 0.0, 2.0 / 3.0];
const SUB_RAYS: usize = OFFSETS.len() * OFFSETS.len();
/// The central sub-ray, the beam's own ray.
const CENTRE: usize = SUB_RAYS / 2;

impl Footprint {
    /// What a beam from `origin` along the unit vector `dir` (world frame) returns, its
    /// footprint sampled by sub-rays; `centre` is its central ray's hit (cast already, with
    /// the sweep). `None` when no sub-ray meets a surface in range.
    #[allow(clippy::too_many_arguments)]
    pub fn beam_return(
        &self,
        caster: &dyn RayCaster,
        mesh: &Mesh,
        origin: &Point3<f32>,
        dir: &Vector3<f32>,
        centre: Option<Hit>,
        t_min: f32,
        t_max: f32,
    ) -> Option<Return> {
        // The footprint's axes: horizontal (along the scan, about the world's z) and
        // vertical; the frame of the beam is the sensor's up to its roll, which is small.
        let h = Vector3::new(-dir.y, dir.x, 0.0);
        let h = if h.norm() > 1e-6 {
            h.normalize()
        } else {
            Vector3::x()
        };
        let v = dir.cross(&h);
        let [half_h, half_v] = self.divergence_rad.map(|a| 0.5 * a);
        let mut dirs = [*dir; SUB_RAYS];
        for (k, d) in dirs.iter_mut().enumerate() {
            let (oh, ov) = (OFFSETS[k / OFFSETS.len()], OFFSETS[k % OFFSETS.len()]);
            if (oh, ov) != (0.0, 0.0) {
                *d = (dir + h * (oh * half_h) + v * (ov * half_v)).normalize();
            }
        }
        let mut sub_hits = [None; SUB_RAYS];
        caster.cast_fan(origin, &dirs, t_min, t_max, &mut sub_hits);
        sub_hits[CENTRE] = centre;
        // (range, energy, ρ cos θ) of every sub-ray that meets a surface, on the stack: this
        // runs for every beam beside an edge.
        let mut hits = [(0.0f32, 0.0f32, 0.0f32); SUB_RAYS];
        let mut n = 0;
        for (hit, d) in sub_hits.iter().zip(&dirs) {
            if let Some(hit) = hit {
                let tri = hit.triangle as usize;
                let rho_cos =
                    mesh.materials[tri].nir_reflectivity() * mesh.normal(tri).dot(d).abs();
                hits[n] = (hit.t, rho_cos / (hit.t * hit.t), rho_cos);
                n += 1;
            }
        }
        self.strongest_or_last(&mut hits[..n])
    }

    /// Groups sub-ray hits `(range, energy, ρ cos θ)` into echoes and picks one.
    fn strongest_or_last(&self, hits: &mut [(f32, f32, f32)]) -> Option<Return> {
        hits.sort_by(|a, b| a.0.total_cmp(&b.0));
        let mut best: Option<(f32, Return)> = None;
        let mut start = 0;
        while start < hits.len() {
            let mut end = start + 1;
            while end < hits.len() && hits[end].0 - hits[end - 1].0 <= self.echo_separation_m {
                end += 1;
            }
            let echo = &hits[start..end];
            let energy: f32 = echo.iter().map(|h| h.1).sum();
            let range = echo.iter().map(|h| h.0 * h.1).sum::<f32>() / energy;
            let intensity = 255.0 * echo.iter().map(|h| h.2).sum::<f32>() / SUB_RAYS as f32;
            let candidate = Return {
                range_m: range,
                intensity,
            };
            let better = match (self.mode, &best) {
                (_, None) => true,
                (ReturnMode::Strongest, Some((e, _))) => energy > *e,
                (ReturnMode::Last, Some(_)) => true,
            };
            if better && energy > 0.0 {
                best = Some((energy, candidate));
            }
            start = end;
        }
        best.map(|(_, r)| r)
    }
}

/// Whether a beam's footprint may straddle an edge: its central ray's range and a scan
/// neighbour's (the same ring, the next column either side) differ by more than 2 cm plus
/// 1 % of the range, or one meets a surface and the other not. The columns of a VLP-16 at
/// 10 Hz lie 3.5 mrad apart, about the footprint's width along the scan, so an edge inside
/// a footprint lies between its ray and a neighbour's. This decides only where sub-rays are
/// cast, not what a beam returns: a beam flagged in vain returns its central ray's surface.
pub fn straddles(centre: Option<f32>, neighbour: Option<f32>) -> bool {
    match (centre, neighbour) {
        (Some(a), Some(b)) => (a - b).abs() > 0.02 + 0.01 * a.min(b),
        (None, None) => false,
        _ => true,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn footprint(mode: ReturnMode) -> Footprint {
        Footprint {
            divergence_rad: [3e-3, 1.5e-3],
            echo_separation_m: 1.0,
            mode,
        }
    }

    #[test]
    fn close_echoes_merge_and_far_ones_are_chosen_by_the_mode() {
        // Four ninths at 3.0 m and five at 3.4 m: one echo between them, weighted by energy.
        let mut hits = vec![(3.0, 1.0 / 9.0, 1.0); 4];
        hits.extend(vec![(3.4, 1.0 / 11.56, 1.0); 5]);
        let r = footprint(ReturnMode::Strongest)
            .strongest_or_last(&mut hits)
            .expect("a return");
        let expected = (4.0 * 3.0 / 9.0 + 5.0 * 3.4 / 11.56) / (4.0 / 9.0 + 5.0 / 11.56);
        assert!((r.range_m - expected).abs() < 1e-5, "{r:?} vs {expected}");
        assert!(r.range_m > 3.0 && r.range_m < 3.4, "a mixed pixel: {r:?}");
        assert!(
            (r.intensity - 255.0).abs() < 1e-3,
            "the whole footprint: {r:?}"
        );

        // Six ninths at 3 m, three at 8 m: two echoes; strongest is the near, last the far.
        let mut hits = vec![(3.0, 1.0 / 9.0, 1.0); 6];
        hits.extend(vec![(8.0, 1.0 / 64.0, 1.0); 3]);
        let strongest = footprint(ReturnMode::Strongest).strongest_or_last(&mut hits.clone());
        let last = footprint(ReturnMode::Last).strongest_or_last(&mut hits);
        assert_eq!(strongest.map(|r| r.range_m), Some(3.0));
        assert_eq!(last.map(|r| r.range_m), Some(8.0));
        assert!((last.expect("last").intensity - 255.0 / 3.0).abs() < 1e-3);
        assert_eq!(footprint(ReturnMode::Last).strongest_or_last(&mut []), None);
    }

    #[test]
    fn straddling_is_a_jump_or_a_miss_beside_a_hit() {
        assert!(
            !straddles(Some(5.0), Some(5.05)),
            "a surface seen obliquely"
        );
        assert!(straddles(Some(5.0), Some(5.2)));
        assert!(straddles(Some(5.0), None));
        assert!(!straddles(None, None));
    }
}
