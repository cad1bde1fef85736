//! A lidar system's map as it saves it to localise in later (issue 46): its keyframes, each
//! a pose in the map and the cloud registered there, in the keyframe's sensor frame.
//!
//! Bytes ([`KEYFRAME_MAP_FORMAT`], little-endian): the keyframe count (u32), then per
//! keyframe `map_from_sensor` as x, y, z, qx, qy, qz, qw (7 x f64), its point count (u32)
//! and the points (3 x f32 each). Version 1 ends there; version 2 (a map made with GNSS,
//! issue 47) adds its georeference `map_from_enu` (the receiver's east-north-up frame in the
//! map, 7 x f64 as above), so that a later run can put its fixes into the map.

use nalgebra::{Isometry3, Quaternion, Translation3, UnitQuaternion};

/// The format's name in a saved map.
pub const KEYFRAME_MAP_FORMAT: &str = "keyframe-clouds";
/// The format's newest version (a map without a georeference is saved as version 1, which
/// every reader since issue 46 reads).
pub const KEYFRAME_MAP_VERSION: u32 = 2;

/// Whether this build reads maps of `version`.
pub fn reads_version(version: u32) -> bool {
    (1..=KEYFRAME_MAP_VERSION).contains(&version)
}

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
    /// Where the GNSS receiver's east-north-up frame lies in the map, if the map was made
    /// with GNSS.
    pub map_from_enu: Option<Isometry3<f64>>,
}

fn push_pose(out: &mut Vec<u8>, pose: &Isometry3<f64>) {
    let t = pose.translation.vector;
    let q = pose.rotation.coords;
    for v in [t.x, t.y, t.z, q.x, q.y, q.z, q.w] {
        out.extend_from_slice(&v.to_le_bytes());
    }
}

impl KeyframeMap {
    /// The version [`KeyframeMap::to_bytes`] writes: 2 with a georeference, else 1.
    pub fn version(&self) -> u32 {
        if self.map_from_enu.is_some() { 2 } else { 1 }
    }

    /// The map's bytes, of [`KeyframeMap::version`].
    pub fn to_bytes(&self) -> Vec<u8> {
        let n: usize = self
            .keyframes
            .iter()
            .map(|k| 60 + 12 * k.points.len())
            .sum();
        let mut out = Vec::with_capacity(4 + n);
        out.extend_from_slice(&(self.keyframes.len() as u32).to_le_bytes());
        for k in &self.keyframes {
            push_pose(&mut out, &k.map_from_sensor);
            out.extend_from_slice(&(k.points.len() as u32).to_le_bytes());
            for p in &k.points {
                for v in p {
                    out.extend_from_slice(&v.to_le_bytes());
                }
            }
        }
        if let Some(georeference) = &self.map_from_enu {
            push_pose(&mut out, georeference);
        }
        out
    }

    /// A map from its bytes of `version` ([`reads_version`]); an error says what is wrong
    /// (cut short, a non-unit rotation, bytes left over).
    pub fn from_bytes(bytes: &[u8], version: u32) -> Result<Self, String> {
        if !reads_version(version) {
            return Err(format!(
                "a {KEYFRAME_MAP_FORMAT} map of version {version}, not 1 to {KEYFRAME_MAP_VERSION}"
            ));
        }
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
        // x, y, z, qx, qy, qz, qw: a pose if finite with a unit rotation.
        let pose = |s: &[u8]| -> Option<Isometry3<f64>> {
            let v: Vec<f64> = s
                .chunks_exact(8)
                .map(|c| f64::from_le_bytes(c.try_into().expect("8 bytes")))
                .collect();
            let q = Quaternion::new(v[6], v[3], v[4], v[5]);
            (v.iter().all(|x| x.is_finite()) && (q.norm() - 1.0).abs() <= 1e-6).then(|| {
                Isometry3::from_parts(
                    Translation3::new(v[0], v[1], v[2]),
                    UnitQuaternion::new_unchecked(q),
                )
            })
        };
        let count = u32_at(take(4)?) as usize;
        let mut keyframes = Vec::with_capacity(count.min(1 << 20));
        for k in 0..count {
            let map_from_sensor = pose(take(56)?)
                .ok_or_else(|| format!("keyframe {k}'s pose is not finite with a unit rotation"))?;
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
                map_from_sensor,
                points,
            });
        }
        let map_from_enu = match version {
            1 => None,
            _ => {
                Some(pose(take(56)?).ok_or("the georeference is not finite with a unit rotation")?)
            }
        };
        if at != bytes.len() {
            return Err(format!(
                "{} bytes after the last keyframe of a {KEYFRAME_MAP_FORMAT} map",
                bytes.len() - at
            ));
        }
        Ok(Self {
            keyframes,
            map_from_enu,
        })
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
            map_from_enu: None,
        };
        let bytes = map.to_bytes();
        assert_eq!((map.version(), bytes.len()), (1, 4 + 2 * 60 + 24));
        assert_eq!(KeyframeMap::from_bytes(&bytes, 1), Ok(map.clone()));
        let cut = KeyframeMap::from_bytes(&bytes[..bytes.len() - 1], 1).expect_err("cut");
        assert!(cut.contains("cut short"), "{cut}");
        let mut extra = bytes.clone();
        extra.push(0);
        assert!(KeyframeMap::from_bytes(&extra, 1).is_err());
        assert!(
            KeyframeMap::from_bytes(&bytes, 2).is_err(),
            "version 2 without its georeference"
        );
        assert!(KeyframeMap::from_bytes(&bytes, 3).is_err());

        // With a georeference: version 2, 56 bytes more, read back bit for bit.
        let georeferenced = KeyframeMap {
            map_from_enu: Some(Isometry3::new(
                nalgebra::Vector3::new(-12.5, 3.25, 0.1),
                nalgebra::Vector3::new(0.0, 0.0, -2.2),
            )),
            ..map
        };
        let bytes = georeferenced.to_bytes();
        assert_eq!(
            (georeferenced.version(), bytes.len()),
            (2, 4 + 2 * 60 + 24 + 56)
        );
        assert_eq!(KeyframeMap::from_bytes(&bytes, 2), Ok(georeferenced));
        let mut bad = bytes.clone();
        let n = bad.len();
        bad[n - 8..].copy_from_slice(&f64::NAN.to_le_bytes());
        let e = KeyframeMap::from_bytes(&bad, 2).expect_err("a NaN georeference");
        assert!(e.contains("georeference"), "{e}");
    }
}
