//! Voxel-grid downsampling: every occupied voxel of edge `leaf` is replaced by the centroid
//! of its points (the filter PCL calls VoxelGrid, used by LOAM and LIO-SAM for their maps).
//! The output is ordered by voxel, so it is deterministic whatever the input order.

use nalgebra::Vector3;

/// Centroids of the occupied voxels of edge `leaf_m`. A non-positive leaf returns the input.
pub fn downsample(points: &[Vector3<f64>], leaf_m: f64) -> Vec<Vector3<f64>> {
    if leaf_m <= 0.0 {
        return points.to_vec();
    }
    let inv = 1.0 / leaf_m;
    let mut keyed: Vec<([i64; 3], u32)> = points
        .iter()
        .enumerate()
        .filter(|(_, p)| p.iter().all(|v| v.is_finite()))
        .map(|(i, p)| {
            (
                [
                    (p.x * inv).floor() as i64,
                    (p.y * inv).floor() as i64,
                    (p.z * inv).floor() as i64,
                ],
                i as u32,
            )
        })
        .collect();
    keyed.sort_unstable();
    let mut out = Vec::new();
    let mut start = 0;
    while start < keyed.len() {
        let key = keyed[start].0;
        let mut end = start;
        let mut sum = Vector3::zeros();
        while end < keyed.len() && keyed[end].0 == key {
            sum += points[keyed[end].1 as usize];
            end += 1;
        }
        out.push(sum / (end - start) as f64);
        start = end;
    }
    out
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
