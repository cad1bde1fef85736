//! A lidar system's map as it saves it to localise in later (issue 46): its keyframes, each
//! a pose in the map and the cloud registered there, in the keyframe's sensor frame.
//!
//! Bytes ([`KEYFRAME_MAP_FORMAT`] version [`KEYFRAME_MAP_VERSION`], little-endian): the
//! keyframe count (u32), then per keyframe `map_from_sensor` as x, y, z, qx, qy, qz, qw
//! (7 x f64), its point count (u32) and the points (3 x f32 each).

use nalgebra::{Isometry3, Quaternion, Translation3, UnitQuaternion};

/// The format's name in a saved map.
pub const KEYFRAME_MAP_FORMAT: &str = "keyframe-clouds";
/// The format's version.
pub const KEYFRAME_MAP_VERSION: u32 = 1;

/// One keyframe of a saved map.
#[derive(Debug, Clone, PartialEq)]
pub struct MapKeyframe {
    pub map_from_sensor: Isometry3<f64>,
    /// The cloud in the keyframe's sensor frame.
    pub points: Vec<[f32; 3]>,
}

/// A saved lidar map: its keyframes in the order they were made.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct KeyframeMap {
    pub keyframes: Vec<MapKeyframe>,
}

impl KeyframeMap {
    /// The map's bytes.
    pub fn to_bytes(&self) -> Vec<u8> {
        let n: usize = self
            .keyframes
            .iter()
            .map(|k| 60 + 12 * k.points.len())
            .sum();
        let mut out = Vec::with_capacity(4 + n);
        out.extend_from_slice(&(self.keyframes.len() as u32).to_le_bytes());
        for k in &self.keyframes {
            let t = k.map_from_sensor.translation.vector;
            let q = k.map_from_sensor.rotation.coords;
            for v in [t.x, t.y, t.z, q.x, q.y, q.z, q.w] {
                out.extend_from_slice(&v.to_le_bytes());
            }
            out.extend_from_slice(&(k.points.len() as u32).to_le_bytes());
            for p in &k.points {
                for v in p {
                    out.extend_from_slice(&v.to_le_bytes());
                }
            }
        }
        out
    }

    /// A map from its bytes; an error says what is wrong (cut short, a non-unit rotation,
    /// bytes left over).
    pub fn from_bytes(bytes: &[u8]) -> Result<Self, String> {
        let mut at = 0usize;
        let mut take = |n: usize| -> Result<&[u8], String> {
            let end = at
                .checked_add(n)
                .filter(|&e| e <= bytes.len())
                .ok_or_else(|| format!("a {KEYFRAME_MAP_FORMAT} map cut short at byte {at}"))?;
            let s = &bytes[at..end];
            at = end;
            Ok(s)
        };
        let u32_at = |s: &[u8]| u32::from_le_bytes(s.try_into().expect("4 bytes"));
        let count = u32_at(take(4)?) as usize;
        let mut keyframes = Vec::with_capacity(count.min(1 << 20));
        for k in 0..count {
            let mut v = [0.0f64; 7];
            for x in &mut v {
                *x = f64::from_le_bytes(take(8)?.try_into().expect("8 bytes"));
            }
            let q = Quaternion::new(v[6], v[3], v[4], v[5]);
            if !v.iter().all(|x| x.is_finite()) || (q.norm() - 1.0).abs() > 1e-6 {
                return Err(format!(
                    "keyframe {k}'s pose is not finite with a unit rotation"
                ));
            }
            let n = u32_at(take(4)?) as usize;
            let raw = take(
                n.checked_mul(12)
                    .ok_or("a point count past the address space")?,
            )?;
            let points = raw
                .chunks_exact(12)
                .map(|c| {
                    [0, 4, 8].map(|i| f32::from_le_bytes(c[i..i + 4].try_into().expect("4 bytes")))
                })
                .collect();
            keyframes.push(MapKeyframe {
                map_from_sensor: Isometry3::from_parts(
                    Translation3::new(v[0], v[1], v[2]),
                    UnitQuaternion::new_unchecked(q),
                ),
                points,
            });
        }
        if at != bytes.len() {
            return Err(format!(
                "{} bytes after the last keyframe of a {KEYFRAME_MAP_FORMAT} map",
                bytes.len() - at
            ));
        }
        Ok(Self { keyframes })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_map_reads_back_bit_for_bit_and_a_cut_one_is_refused() {
        let map = KeyframeMap {
            keyframes: vec![
                MapKeyframe {
                    map_from_sensor: Isometry3::new(
                        nalgebra::Vector3::new(1.0, -2.0, 0.5),
                        nalgebra::Vector3::new(0.0, 0.1, 1.2),
                    ),
                    points: vec![[0.5, 1.5, -0.25], [f32::MIN_POSITIVE, 3.0, 7.0]],
                },
                MapKeyframe {
                    map_from_sensor: Isometry3::identity(),
                    points: Vec::new(),
                },
            ],
        };
        let bytes = map.to_bytes();
        assert_eq!(bytes.len(), 4 + 2 * 60 + 24);
        assert_eq!(KeyframeMap::from_bytes(&bytes), Ok(map));
        let cut = KeyframeMap::from_bytes(&bytes[..bytes.len() - 1]).expect_err("cut");
        assert!(cut.contains("cut short"), "{cut}");
        let mut extra = bytes.clone();
        extra.push(0);
        assert!(KeyframeMap::from_bytes(&extra).is_err());
    }
}
