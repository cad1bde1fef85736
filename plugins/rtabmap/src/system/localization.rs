//! RTAB-Map's localisation mode (`Mem/IncrementalMemory = false`; Labbé and Michaud, JFR
//! 2019, §3 and the RTAB-Map wiki's "localization mode"): the saved map's locations are
//! loaded into working memory, all of them (`Memory::load`: no retrieval from LTM here), and at the detection rate the current frame's signature is compared
//! with them — the Bayes filter's appearance hypothesis verified by PnP on the words the two
//! share, and proximity by scan (ICP of the current scan to a map location's near the
//! estimate) — without ever adding a location to the map. Each accepted match gives the
//! robot's pose in the map, and so `map_from_odom`; between matches, odometry carries it.
//!
//! The status: RTAB-Map publishes no such flag; here the pose is *localised* while one of
//! the last `lost_after` detections (10, ten seconds at RTAB-Map's 1 Hz) was a match, and
//! searching before the first match and after that many without one.
//!
//! The map's bytes ("rtabmap-locations", version 1, little-endian): the location count
//! (u64), then per location its id (u64), stamp (i64), graph pose `map_from_base` (x, y, z,
//! qx, qy, qz, qw: 7 x f64), its features (count u64; per feature the pixel 2 x f32, the
//! descriptor 32 bytes, a flag u8 and, when 1, the 3D point 3 x f64) and its scan (flag u8;
//! when 1, count u64 and 2 x f64 per point, in the scan's frame).

use nalgebra::{Isometry3, Quaternion, Translation3, UnitQuaternion, Vector2, Vector3};
use plugin_api::{PluginError, SavedMap};

use super::Rtabmap;
use crate::features::Features;
use crate::memory::Location;
use crate::pnp::{self, PnpConfig};
use crate::proximity;
use crate::scan_odometry::{planar, spatial};

/// The saved map's format.
pub const FORMAT: &str = "rtabmap-locations";
pub const VERSION: u32 = 1;

/// Detections without a match after which the pose is no longer said localised.
const LOST_AFTER: usize = 10;

/// A localisation run's state.
#[derive(Debug, Default)]
pub(super) struct Localizing {
    /// The map's locations' poses, by id.
    map_poses: Vec<Isometry3<f64>>,
    /// `map_from_odom` from the last match.
    map_from_odom: Option<Isometry3<f64>>,
    /// Detections since the last match (`None`: never matched).
    since_match: Option<usize>,
    /// The last detection's stamp and odometry pose.
    last_detection: Option<(i64, Isometry3<f64>)>,
    /// Appearance and proximity matches made, for the summary.
    pub(super) appearance: usize,
    pub(super) proximity: usize,
    pub(super) detections: usize,
}

impl Localizing {
    pub(super) fn localized(&self) -> bool {
        self.since_match.is_some_and(|n| n < LOST_AFTER)
    }

    pub(super) fn map_from_odom(&self) -> Isometry3<f64> {
        self.map_from_odom.unwrap_or_else(Isometry3::identity)
    }

    /// A guess of the start: `map_from_odom` until the first match (still searching).
    pub(super) fn guess(&mut self, map_from_odom: Isometry3<f64>) {
        self.map_from_odom = Some(map_from_odom);
    }
}

/// Writes and reads the saved map.
struct Bytes<'a>(&'a [u8], usize);

impl Bytes<'_> {
    fn take(&mut self, n: usize) -> Result<&[u8], String> {
        let end = self
            .1
            .checked_add(n)
            .filter(|&e| e <= self.0.len())
            .ok_or_else(|| format!("a {FORMAT} map cut short at byte {}", self.1))?;
        let s = &self.0[self.1..end];
        self.1 = end;
        Ok(s)
    }
    fn u64(&mut self) -> Result<u64, String> {
        Ok(u64::from_le_bytes(
            self.take(8)?.try_into().expect("8 bytes"),
        ))
    }
    fn f64(&mut self) -> Result<f64, String> {
        Ok(f64::from_le_bytes(
            self.take(8)?.try_into().expect("8 bytes"),
        ))
    }
    fn f32(&mut self) -> Result<f32, String> {
        Ok(f32::from_le_bytes(
            self.take(4)?.try_into().expect("4 bytes"),
        ))
    }
    fn count(&mut self, each: usize) -> Result<usize, String> {
        let n = self.u64()? as usize;
        // A count the rest of the bytes cannot hold is a damaged map, not an allocation.
        if n.checked_mul(each)
            .is_none_or(|b| b > self.0.len() - self.1)
        {
            return Err(format!("a {FORMAT} map with an impossible count {n}"));
        }
        Ok(n)
    }
}

fn put_pose(out: &mut Vec<u8>, p: &Isometry3<f64>) {
    let (t, q) = (p.translation.vector, p.rotation.coords);
    for v in [t.x, t.y, t.z, q.x, q.y, q.z, q.w] {
        out.extend_from_slice(&v.to_le_bytes());
    }
}

impl Rtabmap {
    /// The map to localise in later: every location at its graph pose with its features and
    /// scan.
    pub(super) fn saved_map(&self) -> SavedMap {
        let mut out = Vec::new();
        let locations = self.memory.locations();
        out.extend_from_slice(&(locations.len() as u64).to_le_bytes());
        for l in locations {
            out.extend_from_slice(&l.id.to_le_bytes());
            out.extend_from_slice(&l.stamp_ns.to_le_bytes());
            put_pose(&mut out, &self.graph.pose(l.id).unwrap_or(l.odom_from_base));
            let f = &l.features;
            out.extend_from_slice(&(f.len() as u64).to_le_bytes());
            for k in 0..f.len() {
                for v in f.pixels[k] {
                    out.extend_from_slice(&v.to_le_bytes());
                }
                out.extend_from_slice(&f.descriptors[k]);
                match f.points[k] {
                    Some(p) => {
                        out.push(1);
                        for v in [p.x, p.y, p.z] {
                            out.extend_from_slice(&v.to_le_bytes());
                        }
                    }
                    None => out.push(0),
                }
            }
            match &l.scan {
                Some(scan) => {
                    out.push(1);
                    out.extend_from_slice(&(scan.len() as u64).to_le_bytes());
                    for p in scan {
                        out.extend_from_slice(&p.x.to_le_bytes());
                        out.extend_from_slice(&p.y.to_le_bytes());
                    }
                }
                None => out.push(0),
            }
        }
        SavedMap {
            format: FORMAT.into(),
            version: VERSION,
            bytes: out,
        }
    }

    /// Loads a saved map into memory (in its order, as when it was made: the same words),
    /// every location a candidate.
    pub(super) fn load_map(&mut self, bytes: &[u8]) -> Result<(), PluginError> {
        let bad = |e: String| PluginError::new(format!("rtabmap: {e}"));
        let mut b = Bytes(bytes, 0);
        let n = b.count(8).map_err(bad)?;
        let mut poses = Vec::with_capacity(n);
        for expected in 0..n as u64 {
            let id = b.u64().map_err(bad)?;
            if id != expected {
                return Err(bad(format!("location {expected} is numbered {id}")));
            }
            let stamp_ns = b.u64().map_err(bad)? as i64;
            let mut v = [0.0; 7];
            for x in &mut v {
                *x = b.f64().map_err(bad)?;
            }
            let q = Quaternion::new(v[6], v[3], v[4], v[5]);
            if !v.iter().all(|x| x.is_finite()) || (q.norm() - 1.0).abs() > 1e-6 {
                return Err(bad(format!(
                    "location {id}'s pose is not a finite rigid motion"
                )));
            }
            let pose = Isometry3::from_parts(
                Translation3::new(v[0], v[1], v[2]),
                UnitQuaternion::new_unchecked(q),
            );
            let k = b.count(41).map_err(bad)?;
            let mut features = Features {
                pixels: Vec::with_capacity(k),
                descriptors: Vec::with_capacity(k),
                points: Vec::with_capacity(k),
            };
            for _ in 0..k {
                features
                    .pixels
                    .push([b.f32().map_err(bad)?, b.f32().map_err(bad)?]);
                features
                    .descriptors
                    .push(b.take(32).map_err(bad)?.try_into().expect("32 bytes"));
                features.points.push(match b.take(1).map_err(bad)?[0] {
                    0 => None,
                    _ => Some(Vector3::new(
                        b.f64().map_err(bad)?,
                        b.f64().map_err(bad)?,
                        b.f64().map_err(bad)?,
                    )),
                });
            }
            let scan = match b.take(1).map_err(bad)?[0] {
                0 => None,
                _ => {
                    let m = b.count(16).map_err(bad)?;
                    let mut points = Vec::with_capacity(m);
                    for _ in 0..m {
                        points.push(Vector2::new(b.f64().map_err(bad)?, b.f64().map_err(bad)?));
                    }
                    Some(points)
                }
            };
            self.memory.load(Location {
                id,
                stamp_ns,
                odom_from_base: pose,
                features,
                words: Vec::new(),
                scan,
                cloud: Vec::new(),
            });
            poses.push(pose);
        }
        if b.1 != bytes.len() {
            return Err(bad(format!(
                "{} bytes after the last location",
                bytes.len() - b.1
            )));
        }
        self.localizing = Some(Localizing {
            map_poses: poses,
            ..Localizing::default()
        });
        Ok(())
    }

    /// Whether a detection is due (the mapping mode's rule: a period since the last one,
    /// and moved).
    pub(super) fn detection_due(&self, stamp_ns: i64, odom_from_base: &Isometry3<f64>) -> bool {
        let Some((last_ns, last)) = self.localizing.as_ref().and_then(|l| l.last_detection) else {
            return true;
        };
        let period_ns = (1e9 / self.cfg.memory.detection_rate_hz) as i64;
        if stamp_ns - last_ns < period_ns - 16_000_000 {
            return false;
        }
        let moved = last.inverse() * odom_from_base;
        moved.translation.vector.norm() >= self.cfg.memory.linear_update_m
            || moved.rotation.angle() >= self.cfg.memory.angular_update_rad
    }

    /// One detection in localisation mode: appearance, then proximity; a match sets
    /// `map_from_odom`.
    pub(super) fn detect_in_map(
        &mut self,
        stamp_ns: i64,
        odom_from_base: Isometry3<f64>,
        features: Features,
    ) -> Result<(), PluginError> {
        let features = features.truncated(self.cfg.memory.max_words);
        let (words, hypothesis) = self.memory.detect(&features);
        let mut found = None;
        if let Some(h) = hypothesis
            && self.cfg.loop_closure.enabled
        {
            let (object, pixels) = self.memory.correspondences_to(h.id, &words, &features);
            let pnp_cfg = PnpConfig {
                reprojection_px: self.cfg.visual.pnp_reprojection_px,
                iterations: self.cfg.visual.pnp_iterations,
            };
            let solved = pnp::solve(&object, &pixels, self.intrinsics, None, &pnp_cfg)
                .map_err(|e| PluginError::new(format!("OpenCV PnP: {e}")))?;
            let inliers = solved.as_ref().map_or(0, |r| r.inliers.len());
            match solved.filter(|r| r.inliers.len() >= self.cfg.loop_closure.min_inliers) {
                Some(result) => {
                    let camera_old_from_camera_new = result.camera_from_object.inverse();
                    let mut old_from_new = self.base_from_camera
                        * camera_old_from_camera_new
                        * self.base_from_camera.inverse();
                    if self.cfg.odometry == crate::config::OdometrySource::WheelIcp
                        && self.cfg.icp.attitude_gain == 0.0
                    {
                        old_from_new = spatial(&planar(&old_from_new));
                    }
                    if let Some(l) = &mut self.localizing {
                        found = Some(l.map_poses[h.id as usize] * old_from_new);
                        l.appearance += 1;
                    }
                }
                None => {
                    let _ = inliers;
                }
            }
        }
        if found.is_none() && self.cfg.proximity.enabled {
            found = self.proximity_in_map(&odom_from_base)?;
        }
        let l = self.localizing.as_mut().expect("localising");
        l.detections += 1;
        l.last_detection = Some((stamp_ns, odom_from_base));
        match found {
            Some(map_from_base) => {
                l.map_from_odom = Some(map_from_base * odom_from_base.inverse());
                l.since_match = Some(0);
            }
            None => l.since_match = l.since_match.map(|n| n + 1),
        }
        Ok(())
    }

    /// Proximity in the map: once localised, the current scan registered by ICP to the
    /// nearest map location's (with its neighbours') near the estimate; the pose in the map
    /// if it matches.
    fn proximity_in_map(
        &mut self,
        odom_from_base: &Isometry3<f64>,
    ) -> Result<Option<Isometry3<f64>>, PluginError> {
        let Some(l) = self.localizing.as_ref() else {
            return Ok(None);
        };
        let (Some(map_from_odom), Some((_, scan))) = (l.map_from_odom, self.latest_scan.as_ref())
        else {
            return Ok(None);
        };
        let estimate = map_from_odom * odom_from_base;
        let this = proximity::Candidate {
            id: u64::MAX,
            // Every map location is older than this run: none is excluded by age.
            stamp_ns: i64::MAX / 2,
            map_from_base: planar(&estimate),
        };
        let poses = &l.map_poses;
        let candidates = self
            .memory
            .locations()
            .iter()
            .filter(|m| m.scan.is_some())
            .map(|m| proximity::Candidate {
                id: m.id,
                stamp_ns: m.stamp_ns,
                map_from_base: planar(&poses[m.id as usize]),
            });
        let Some(old) = proximity::nearest(&this, candidates, &self.cfg.proximity) else {
            return Ok(None);
        };
        let reach = self.cfg.proximity.submap_neighbours as u64;
        let last = self.memory.locations().len() as u64 - 1;
        let mut old_scan = Vec::new();
        for m in &self.memory.locations()
            [old.id.saturating_sub(reach) as usize..=(old.id + reach).min(last) as usize]
        {
            if let Some(s) = &m.scan {
                let old_from_m = old.map_from_base.inverse() * planar(&poses[m.id as usize]);
                old_scan.extend(
                    self.scan_in_base(s)
                        .iter()
                        .map(|p| (old_from_m * nalgebra::Point2::from(*p)).coords),
                );
            }
        }
        let new_scan = self.scan_in_base(scan);
        let guess = old.map_from_base.inverse() * this.map_from_base;
        let Ok(result) = proximity::register(
            &old_scan,
            &new_scan,
            guess,
            &self.cfg.icp.icp,
            &self.cfg.proximity,
        ) else {
            return Ok(None);
        };
        let old_pose = poses[old.id as usize];
        let planar_map = old.map_from_base * result.target_from_source;
        // ICP measures x, y and yaw; height, roll and pitch stay as the estimate has them.
        let (roll, pitch, _) = estimate.rotation.euler_angles();
        let lifted =
            crate::scan_odometry::raised(&planar_map, old_pose.translation.vector.z, roll, pitch);
        if let Some(l) = &mut self.localizing {
            l.proximity += 1;
        }
        Ok(Some(lifted))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A damaged map is an error naming what is wrong, never a panic or a huge allocation.
    #[test]
    fn a_cut_or_inflated_map_is_refused() {
        let mut b = Bytes(&[5, 0, 0, 0, 0, 0, 0, 0], 0);
        assert!(
            b.count(8)
                .expect_err("5 locations in no bytes")
                .contains("impossible count")
        );
        let mut b = Bytes(&[1, 2, 3], 0);
        assert!(b.u64().expect_err("cut").contains("cut short"));
    }
}
