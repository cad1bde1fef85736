//! The map saved at the end of a mapping run and loaded to localise in (issue 46): what
//! ORB-SLAM2's localisation mode needs of a map — every live keyframe (its pose, keypoints,
//! depths, descriptors and which map point each keypoint sees) and every live map point
//! (position, representative descriptor, viewing direction, scale-invariance distances).
//! What can be recomputed is not saved: each keyframe's bag of words (from its descriptors
//! with the vocabulary), the keyframe database, the points' observations (from the
//! keyframes) and the covisibility graph. Ids are renumbered densely in map order.
//!
//! Bytes ([`ORB_MAP_FORMAT`] version [`ORB_MAP_VERSION`], little-endian): the keyframe count
//! (u32); per keyframe its stamp (i64), `camera_from_world` as x, y, z, qx, qy, qz, qw
//! (7 × f64) and its keypoint count (u32), then per keypoint u, v, angle, response, size
//! (5 × f32), octave (u8), depth and right coordinate (2 × f64, negative: none), the
//! descriptor (32 bytes) and its map point (u32, `u32::MAX`: none); then the point count
//! (u32) and per point its position (3 × f64), descriptor (32 bytes), normal (3 × f64), min
//! and max distance (2 × f64) and reference keyframe (u32).

use std::collections::BTreeMap;

use nalgebra::{Isometry3, Quaternion, Translation3, UnitQuaternion, Vector3};
use slam_common::place::vocabulary::Vocabulary;

use crate::database::KeyFrameDatabase;
use crate::frame::{Camera, Descriptor, Frame};
use crate::map::{Map, MapPoint};
use crate::orb::KeyPoint;

/// The format's name in a saved map.
pub const ORB_MAP_FORMAT: &str = "orbslam2-map";
/// The format's version.
pub const ORB_MAP_VERSION: u32 = 1;

const NONE: u32 = u32::MAX;

/// The live part of `map` as bytes.
pub fn to_bytes(map: &Map) -> Vec<u8> {
    let keyframes: Vec<usize> = map.live_keyframes().map(|k| k.id).collect();
    let kf_index: BTreeMap<usize, u32> = keyframes
        .iter()
        .enumerate()
        .map(|(i, &k)| (k, i as u32))
        .collect();
    // Live points seen by a live keyframe, in id order.
    let points: Vec<usize> = (0..map.points.len())
        .filter(|&p| {
            let point = &map.points[p];
            !point.bad && point.observations.keys().any(|k| kf_index.contains_key(k))
        })
        .collect();
    let point_index: BTreeMap<usize, u32> = points
        .iter()
        .enumerate()
        .map(|(i, &p)| (p, i as u32))
        .collect();
    let mut out = Vec::new();
    let put_f64 = |out: &mut Vec<u8>, v: f64| out.extend_from_slice(&v.to_le_bytes());
    let put_f32 = |out: &mut Vec<u8>, v: f32| out.extend_from_slice(&v.to_le_bytes());
    let put_u32 = |out: &mut Vec<u8>, v: u32| out.extend_from_slice(&v.to_le_bytes());
    put_u32(&mut out, keyframes.len() as u32);
    for &k in &keyframes {
        let f = &map.keyframes[k].frame;
        out.extend_from_slice(&f.stamp_ns.to_le_bytes());
        let t = f.camera_from_world.translation.vector;
        let q = f.camera_from_world.rotation.coords;
        for v in [t.x, t.y, t.z, q.x, q.y, q.z, q.w] {
            put_f64(&mut out, v);
        }
        put_u32(&mut out, f.len() as u32);
        for i in 0..f.len() {
            let key = &f.keys[i];
            for v in [key.u, key.v, key.angle_deg, key.response, key.size] {
                put_f32(&mut out, v);
            }
            out.push(key.octave);
            put_f64(&mut out, f.depth[i]);
            put_f64(&mut out, f.u_right[i]);
            out.extend_from_slice(&f.descriptors[i]);
            let p = f.points[i]
                .and_then(|p| point_index.get(&p).copied())
                .unwrap_or(NONE);
            put_u32(&mut out, p);
        }
    }
    put_u32(&mut out, points.len() as u32);
    for &p in &points {
        let point = &map.points[p];
        for v in point.world.iter().copied() {
            put_f64(&mut out, v);
        }
        out.extend_from_slice(&point.descriptor);
        for v in point.normal.iter().copied() {
            put_f64(&mut out, v);
        }
        put_f64(&mut out, point.min_distance);
        put_f64(&mut out, point.max_distance);
        let reference = kf_index
            .get(&point.reference_kf)
            .or_else(|| point.observations.keys().find_map(|k| kf_index.get(k)))
            .copied()
            .expect("a saved point has a live keyframe");
        put_u32(&mut out, reference);
    }
    out
}

/// A reader over the bytes that names where they end too soon.
struct Reader<'a> {
    bytes: &'a [u8],
    at: usize,
}

impl<'a> Reader<'a> {
    fn take(&mut self, n: usize) -> Result<&'a [u8], String> {
        let end = self
            .at
            .checked_add(n)
            .filter(|&e| e <= self.bytes.len())
            .ok_or_else(|| format!("an {ORB_MAP_FORMAT} map cut short at byte {}", self.at))?;
        let s = &self.bytes[self.at..end];
        self.at = end;
        Ok(s)
    }

    fn u32(&mut self) -> Result<u32, String> {
        Ok(u32::from_le_bytes(self.take(4)?.try_into().expect("4")))
    }

    fn f32(&mut self) -> Result<f32, String> {
        Ok(f32::from_le_bytes(self.take(4)?.try_into().expect("4")))
    }

    fn f64(&mut self) -> Result<f64, String> {
        let v = f64::from_le_bytes(self.take(8)?.try_into().expect("8"));
        if v.is_finite() {
            Ok(v)
        } else {
            Err(format!(
                "a non-finite number at byte {} of an {ORB_MAP_FORMAT} map",
                self.at - 8
            ))
        }
    }

    fn descriptor(&mut self) -> Result<Descriptor, String> {
        Ok(self.take(32)?.try_into().expect("32"))
    }
}

/// A map from its bytes, ready to localise in: the points' observations, every keyframe's
/// bag of words and covisibility, and the keyframe database rebuilt. An error says what is
/// wrong (cut short, a number out of range, bytes left over).
pub fn from_bytes(
    bytes: &[u8],
    camera: &Camera,
    vocabulary: &Vocabulary,
) -> Result<(Map, KeyFrameDatabase), String> {
    let mut r = Reader { bytes, at: 0 };
    let count = r.u32()? as usize;
    let mut frames = Vec::with_capacity(count.min(1 << 16));
    let mut references = Vec::new();
    for k in 0..count {
        let stamp_ns = i64::from_le_bytes(r.take(8)?.try_into().expect("8"));
        let mut v = [0.0f64; 7];
        for x in &mut v {
            *x = r.f64()?;
        }
        let q = Quaternion::new(v[6], v[3], v[4], v[5]);
        if (q.norm() - 1.0).abs() > 1e-6 {
            return Err(format!("keyframe {k}'s rotation is not a unit quaternion"));
        }
        let n = r.u32()? as usize;
        let (mut keys, mut descriptors) = (Vec::new(), Vec::new());
        let (mut depth, mut u_right, mut points) = (Vec::new(), Vec::new(), Vec::new());
        for _ in 0..n {
            let mut f = [0.0f32; 5];
            for x in &mut f {
                *x = r.f32()?;
            }
            if !f.iter().all(|x| x.is_finite()) {
                return Err(format!("keyframe {k} has a non-finite keypoint"));
            }
            let octave = r.take(1)?[0];
            if usize::from(octave) >= camera.levels() {
                return Err(format!(
                    "keyframe {k} has a keypoint on pyramid level {octave}, the camera has {}",
                    camera.levels()
                ));
            }
            keys.push(KeyPoint {
                u: f[0],
                v: f[1],
                angle_deg: f[2],
                response: f[3],
                size: f[4],
                octave,
            });
            depth.push(r.f64()?);
            u_right.push(r.f64()?);
            descriptors.push(r.descriptor()?);
            points.push(r.u32()?);
        }
        let mut frame = Frame::from_parts(stamp_ns, camera, keys, descriptors, depth, u_right);
        frame.camera_from_world = Isometry3::from_parts(
            Translation3::new(v[0], v[1], v[2]),
            UnitQuaternion::new_unchecked(q),
        );
        frames.push(frame);
        references.push(points);
    }
    let point_count = r.u32()? as usize;
    let mut map = Map::default();
    for p in 0..point_count {
        let world = Vector3::new(r.f64()?, r.f64()?, r.f64()?);
        let descriptor = r.descriptor()?;
        let normal = Vector3::new(r.f64()?, r.f64()?, r.f64()?);
        let (min_distance, max_distance) = (r.f64()?, r.f64()?);
        let reference_kf = r.u32()? as usize;
        if reference_kf >= count {
            return Err(format!(
                "point {p}'s reference keyframe {reference_kf} is not among the {count}"
            ));
        }
        map.points.push(MapPoint {
            world,
            descriptor,
            observations: BTreeMap::new(),
            normal,
            min_distance,
            max_distance,
            reference_kf,
            first_kf: reference_kf,
            visible: 1,
            found: 1,
            bad: false,
            replaced_by: None,
        });
    }
    if r.at != bytes.len() {
        return Err(format!(
            "{} bytes after the last point of an {ORB_MAP_FORMAT} map",
            bytes.len() - r.at
        ));
    }
    for (k, (mut frame, refs)) in frames.into_iter().zip(references).enumerate() {
        for (i, &p) in refs.iter().enumerate() {
            if p == NONE {
                continue;
            }
            if p as usize >= point_count {
                return Err(format!(
                    "keyframe {k} sees point {p}, the map has {point_count}"
                ));
            }
            frame.points[i] = Some(p as usize);
        }
        frame.compute_bow(vocabulary);
        let id = map.add_keyframe(frame);
        map.keyframes[id].keep = true;
    }
    let mut database = KeyFrameDatabase::default();
    for k in 0..map.keyframes.len() {
        map.update_connections(k);
        database.add(&map, k);
    }
    Ok((map, database))
}

#[cfg(test)]
mod tests {
    use std::collections::BTreeSet;

    use rand::{Rng, SeedableRng};
    use slam_common::place::vocabulary::TrainConfig;

    use super::*;
    use crate::matcher::tests::{keyframe, scene};

    /// A map of two keyframes, the second seeing half the first one's points: saved and
    /// loaded it saves the same bytes again, with the observations, bags of words,
    /// covisibility and database rebuilt; a map cut short, with a byte left over, or naming
    /// a point it lacks is refused with what is wrong.
    #[test]
    fn a_map_reads_back_whole_and_a_damaged_one_is_refused() {
        let (camera, mut frame, _) = scene();
        // A vocabulary of two images, so that words have weight (idf) in one of them.
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(9);
        let others: Vec<Descriptor> = (0..400).map(|_| rng.random()).collect();
        let vocabulary = Vocabulary::train(
            &[frame.descriptors.clone(), others],
            &TrainConfig {
                k: 10,
                levels: 3,
                ..TrainConfig::default()
            },
        )
        .expect("trains");
        frame.bow = Default::default();
        frame.compute_bow(&vocabulary);
        assert!(!frame.bow.entries.is_empty());
        let mut map = Map::default();
        let a = keyframe(&mut map, &camera, &frame);
        let mut second = frame.clone();
        second.camera_from_world = Isometry3::translation(-0.5, 0.0, 0.0);
        second.points = (0..second.len())
            .map(|i| {
                (i % 2 == 0)
                    .then(|| map.keyframes[a].frame.points[i])
                    .flatten()
            })
            .collect();
        let b = map.add_keyframe(second);
        map.update_connections(a);
        map.update_connections(b);
        let bytes = to_bytes(&map);
        let (loaded, database) = from_bytes(&bytes, &camera, &vocabulary).expect("reads");
        assert_eq!(to_bytes(&loaded), bytes, "saved again, the same bytes");
        assert_eq!(loaded.keyframes.len(), 2);
        assert_eq!(loaded.points.len(), 400);
        assert_eq!(loaded.points[0].observations.len(), 2, "seen by both");
        assert_eq!(loaded.points[1].observations.len(), 1);
        assert_eq!(loaded.keyframes[1].frame.bow, map.keyframes[a].frame.bow);
        assert_eq!(loaded.keyframes[0].covisibility.get(&1), Some(&200));
        let candidates = database.candidates(&loaded, &frame.bow, &BTreeSet::new(), 0.0, 0.8, 0.75);
        assert!(!candidates.is_empty(), "the database finds the keyframes");

        let cut = from_bytes(&bytes[..bytes.len() - 1], &camera, &vocabulary).expect_err("cut");
        assert!(cut.contains("cut short"), "{cut}");
        let mut extra = bytes.clone();
        extra.push(0);
        let extra = from_bytes(&extra, &camera, &vocabulary).expect_err("extra");
        assert!(extra.contains("1 bytes after the last point"), "{extra}");
        // The first keypoint's map point (after the keyframe count, stamp, pose, keypoint
        // count and the keypoint's 5 floats, octave, 2 depths and descriptor) set past the
        // points.
        let at = 4 + 8 + 56 + 4 + 20 + 1 + 16 + 32;
        let mut foreign = bytes.clone();
        foreign[at..at + 4].copy_from_slice(&4000u32.to_le_bytes());
        let foreign = from_bytes(&foreign, &camera, &vocabulary).expect_err("foreign");
        assert!(
            foreign.contains("sees point 4000, the map has 400"),
            "{foreign}"
        );
    }
}
