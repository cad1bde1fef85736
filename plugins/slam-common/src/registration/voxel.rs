//! Voxel-grid downsampling: every occupied voxel of edge `leaf` is replaced by the centroid
//! of its points (the filter PCL calls VoxelGrid, used by LOAM and LIO-SAM for their maps).
//! The output is ordered by voxel, so it is deterministic whatever the input order.

use std::collections::HashMap;
use std::hash::{BuildHasherDefault, Hasher};

use nalgebra::Vector3;

/// Centroids of the occupied voxels of edge `leaf_m`. A non-positive leaf returns the input.
///
/// Points are summed per voxel in a hash map (one pass), and only the occupied voxels are
/// sorted, so that the output order depends on the geometry alone.
pub fn downsample(points: &[Vector3<f64>], leaf_m: f64) -> Vec<Vector3<f64>> {
    if leaf_m <= 0.0 {
        return points.to_vec();
    }
    let inv = 1.0 / leaf_m;
    let mut voxels: HashMap<[i64; 3], (Vector3<f64>, u32), BuildHasherDefault<VoxelHasher>> =
        HashMap::with_capacity_and_hasher(points.len() / 4, BuildHasherDefault::default());
    for p in points.iter().filter(|p| p.iter().all(|v| v.is_finite())) {
        let key = [
            (p.x * inv).floor() as i64,
            (p.y * inv).floor() as i64,
            (p.z * inv).floor() as i64,
        ];
        let entry = voxels.entry(key).or_insert((Vector3::zeros(), 0));
        entry.0 += p;
        entry.1 += 1;
    }
    let mut cells: Vec<([i64; 3], Vector3<f64>)> = voxels
        .into_iter()
        .map(|(k, (sum, n))| (k, sum / n as f64))
        .collect();
    cells.sort_unstable_by_key(|c| c.0);
    cells.into_iter().map(|(_, c)| c).collect()
}

/// A multiplicative hash for voxel keys (the FxHash scheme): keys are small integers that
/// need no protection against adversarial collisions, and SipHash would cost more than the
/// summing itself. Deterministic, unlike the standard library's seeded default.
#[derive(Debug, Default, Clone, Copy)]
struct VoxelHasher(u64);

impl Hasher for VoxelHasher {
    fn finish(&self) -> u64 {
        self.0
    }

    fn write(&mut self, bytes: &[u8]) {
        for chunk in bytes.chunks(8) {
            let mut word = [0u8; 8];
            word[..chunk.len()].copy_from_slice(chunk);
            self.write_u64(u64::from_le_bytes(word));
        }
    }

    fn write_u64(&mut self, v: u64) {
        self.0 = (self.0.rotate_left(5) ^ v).wrapping_mul(0x51_7c_c1_b7_27_22_0a_95);
    }

    fn write_i64(&mut self, v: i64) {
        self.write_u64(v as u64);
    }

    fn write_usize(&mut self, v: usize) {
        self.write_u64(v as u64);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn one_centroid_per_voxel() {
        let points = vec![
            Vector3::new(0.1, 0.1, 0.1),
            Vector3::new(0.3, 0.1, 0.1),
            Vector3::new(1.2, 0.1, 0.1),
            Vector3::new(-0.1, 0.1, 0.1),
        ];
        let out = downsample(&points, 0.5);
        assert_eq!(out.len(), 3, "three voxels are occupied: {out:?}");
        assert!(
            out.contains(&Vector3::new(0.2, 0.1, 0.1)),
            "centroid of the first two: {out:?}"
        );
        let reversed: Vec<_> = points.iter().rev().copied().collect();
        assert_eq!(
            downsample(&reversed, 0.5),
            out,
            "order of the input does not matter"
        );
    }
}
