//! The two 2D lidars merged into one scan about the base, as a Thorvald's navigation feeds
//! AMCL: each scan's returns put into the base frame, then projected into one virtual
//! scan at the base's origin, each angular bin keeping its nearest return (the method of
//! `ira_laser_tools`' `laserscan_multi_merger`, which Thorvald's configurations use, and of
//! `pointcloud_to_laserscan`).

use crate::Pose2;

/// One scan: its sensor's pose on the base, its geometry and its ranges (metres; a value
/// outside `[range_min, range_max)` or not finite is no return).
#[derive(Debug, Clone, Copy)]
pub struct Scan<'a> {
    pub base_from_sensor: Pose2,
    pub angle_min: f64,
    pub angle_increment: f64,
    pub range_min: f64,
    pub range_max: f64,
    pub ranges: &'a [f32],
}

/// The merged scan's geometry, about the base's origin.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct VirtualScan {
    pub angle_min: f64,
    pub angle_increment: f64,
    pub beams: usize,
    pub range_min: f64,
    pub range_max: f64,
}

impl VirtualScan {
    /// A full turn from -π in `beams` bins.
    pub fn full_turn(beams: usize, range_min: f64, range_max: f64) -> Self {
        Self {
            angle_min: -std::f64::consts::PI,
            angle_increment: std::f64::consts::TAU / beams as f64,
            beams,
            range_min,
            range_max,
        }
    }

    /// The scans merged: per bin the nearest return within the range window.
    pub fn merge(&self, scans: &[Scan<'_>]) -> Vec<Option<f64>> {
        let mut out: Vec<Option<f64>> = vec![None; self.beams];
        for scan in scans {
            for (k, &r) in scan.ranges.iter().enumerate() {
                let r = f64::from(r);
                if !(r.is_finite() && r >= scan.range_min && r < scan.range_max) {
                    continue;
                }
                let a = scan.angle_min + k as f64 * scan.angle_increment;
                let [x, y] = scan.base_from_sensor.transform([r * a.cos(), r * a.sin()]);
                let range = x.hypot(y);
                if !(range >= self.range_min && range < self.range_max) {
                    continue;
                }
                let bearing = y.atan2(x);
                let bin = ((bearing - self.angle_min) / self.angle_increment).floor();
                if bin < 0.0 || bin as usize >= self.beams {
                    continue;
                }
                let slot = &mut out[bin as usize];
                if slot.is_none_or(|old| range < old) {
                    *slot = Some(range);
                }
            }
        }
        out
    }

    /// The merged ranges' end points in the base frame, at each bin's centre bearing.
    pub fn end_points(&self, ranges: &[Option<f64>]) -> Vec<Option<[f64; 2]>> {
        ranges
            .iter()
            .enumerate()
            .map(|(k, r)| {
                r.map(|r| {
                    let a = self.angle_min + (k as f64 + 0.5) * self.angle_increment;
                    [r * a.cos(), r * a.sin()]
                })
            })
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A scanner at `pose` on the base, 270° wide at 0.5°, in a square room of half side
    /// 5 m centred on the base.
    fn room_scan(pose: Pose2) -> Vec<f32> {
        (0..541)
            .map(|k| {
                let a = (-135.0 + 0.5 * k as f64).to_radians() + pose.theta;
                let (c, s) = (a.cos(), a.sin());
                // Distance from (pose.x, pose.y) along (c, s) to the walls at ±5.
                let tx = if c > 0.0 {
                    (5.0 - pose.x) / c
                } else {
                    (-5.0 - pose.x) / c
                };
                let ty = if s > 0.0 {
                    (5.0 - pose.y) / s
                } else {
                    (-5.0 - pose.y) / s
                };
                tx.min(ty) as f32
            })
            .collect()
    }

    #[test]
    fn two_scanners_merge_into_one_full_turn_on_the_walls() {
        let front = Pose2::new(0.8, 0.0, 0.0);
        let back = Pose2::new(-0.8, 0.0, std::f64::consts::PI);
        let (rf, rb) = (room_scan(front), room_scan(back));
        let scan = |pose, ranges| Scan {
            base_from_sensor: pose,
            angle_min: (-135f64).to_radians(),
            angle_increment: 0.5f64.to_radians(),
            range_min: 0.1,
            range_max: 30.0,
            ranges,
        };
        let v = VirtualScan::full_turn(360, 0.1, 30.0);
        let merged = v.merge(&[scan(front, &rf), scan(back, &rb)]);
        // Every bin of the full turn has a return: the two 270° fans cover it.
        assert!(
            merged.iter().all(Option::is_some),
            "{} empty bins",
            merged.iter().filter(|r| r.is_none()).count()
        );
        // Every end point lies on a wall (within the bin's angular width at 7 m: 0.13 m).
        for p in v.end_points(&merged).into_iter().flatten() {
            let wall = (p[0].abs() - 5.0).abs().min((p[1].abs() - 5.0).abs());
            assert!(wall < 0.13, "{p:?} is {wall} m off the walls");
        }
        // A return outside the window is no return.
        let mut short = rf.clone();
        short.iter_mut().for_each(|r| *r = 0.05);
        assert!(v.merge(&[scan(front, &short)]).iter().all(Option::is_none));
    }
}
