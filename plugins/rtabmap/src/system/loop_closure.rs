//! Loop closure: a new location against the old ones, by appearance (the Bayes filter's
//! hypothesis, verified by PnP on the words the two share) and by proximity (the new scan
//! registered by ICP to an old location's scans near it in the graph). Either way the link
//! goes into the graph, whose optimisation check may still reject it (RTAB-Map's
//! `RGBD/OptimizeMaxError`): Labbé and Michaud, "RTAB-Map as an open-source lidar and
//! visual SLAM library for large-scale and long-term online operation", JFR 36(2), 2019.

use nalgebra::{Isometry3, Point3, Vector2, Vector3};
use plugin_api::{Event, EventKind, PluginError};

use super::Rtabmap;
use crate::config::OdometrySource;
use crate::graph::{LinkKind, LoopOutcome, PoseGraph, Sigmas, Strain};
use crate::memory::{Hypothesis, Location};
use crate::pnp::{self, PnpConfig};
use crate::proximity;
use crate::scan_odometry::{narrow_returns, planar, raised, spatial};

impl Rtabmap {
    /// A loop closure between location `new` and the older `old`, at `new`'s stamp.
    fn loop_event(&mut self, kind: EventKind, new: u64, old: u64, detail: String) {
        let (new_ns, old_ns) = (
            self.memory.location(new).stamp_ns,
            self.memory.location(old).stamp_ns,
        );
        self.events
            .push(Event::loop_closure(new_ns, kind, [new_ns, old_ns], detail));
    }

    /// Verifies a hypothesis by PnP and, if it holds, adds it to the graph, where the
    /// optimisation check may still reject it.
    pub(super) fn close_loop(&mut self, new: u64, h: Hypothesis) -> Result<(), PluginError> {
        let cfg = self.cfg.loop_closure.clone();
        let (old_stamp, new_stamp) = (
            self.memory.location(h.id).stamp_ns,
            self.memory.location(new).stamp_ns,
        );
        let head = format!(
            "location {new} (t_ns={new_stamp}) with location {} (t_ns={old_stamp}), posterior {:.3}",
            h.id, h.posterior
        );
        let (object, pixels) = self.memory.correspondences(h.id, new);
        let pnp_cfg = PnpConfig {
            reprojection_px: self.cfg.visual.pnp_reprojection_px,
            iterations: self.cfg.visual.pnp_iterations,
        };
        let intrinsics = self.intrinsics;
        let solved = pnp::solve(&object, &pixels, intrinsics, None, &pnp_cfg)
            .map_err(|e| Self::error("OpenCV PnP")(e.to_string()))?;
        let inliers = solved.as_ref().map_or(0, |r| r.inliers.len());
        let Some(result) = solved.filter(|r| r.inliers.len() >= cfg.min_inliers) else {
            self.loop_event(
                EventKind::LoopClosureRejected,
                new,
                h.id,
                format!(
                    "{head}: verification failed, {inliers} PnP inliers of {} words in common (need {})",
                    object.len(),
                    cfg.min_inliers
                ),
            );
            return Ok(());
        };
        // camera_new_from_camera_old → base_old_from_base_new.
        let camera_old_from_camera_new = result.camera_from_object.inverse();
        let mut old_from_new =
            self.base_from_camera * camera_old_from_camera_new * self.base_from_camera.inverse();
        // Planar odometry (no attitude) keeps every pose level: so must the link.
        if self.cfg.odometry == OdometrySource::WheelIcp && self.cfg.icp.attitude_gain == 0.0 {
            old_from_new = spatial(&planar(&old_from_new));
        }
        let sigmas = self.loop_sigmas(&object, &pixels, &result);
        self.add_loop_link(
            h.id,
            new,
            old_from_new,
            sigmas,
            &format!("{head}: {inliers} PnP inliers"),
        )
    }

    /// Adds a verified loop link `old → new` to the graph and says what became of it.
    fn add_loop_link(
        &mut self,
        old: u64,
        new: u64,
        old_from_new: Isometry3<f64>,
        sigmas: Sigmas,
        what: &str,
    ) -> Result<(), PluginError> {
        let outcome = self
            .graph
            .add_loop(old, new, old_from_new, sigmas)
            .map_err(|e| Self::error("factor graph")(e.to_string()))?;
        let strain = |s: &Strain| {
            format!(
                "worst link {:.2} sigma ({} {}-{})",
                s.ratio,
                match s.kind {
                    LinkKind::Odometry => "odometry",
                    LinkKind::Loop => "loop",
                },
                s.from,
                s.to
            )
        };
        match outcome {
            LoopOutcome::Accepted(s) => self.loop_event(
                EventKind::LoopClosureAccepted,
                new,
                old,
                format!("{what}, {}", strain(&s)),
            ),
            LoopOutcome::Rejected(s) => self.loop_event(
                EventKind::LoopClosureRejected,
                new,
                old,
                format!(
                    "{what}, but after optimisation {} > {} (OptimizeMaxError); graph restored",
                    strain(&s),
                    self.cfg.loop_closure.optimize_max_error
                ),
            ),
        }
        Ok(())
    }

    /// Proximity detection: registers the new location's scan to the nearest old location's
    /// near it in the graph.
    pub(super) fn close_by_proximity(&mut self, new: u64) -> Result<(), PluginError> {
        let planar_pose =
            |graph: &PoseGraph, l: &Location| planar(&graph.pose(l.id).unwrap_or(l.odom_from_base));
        let newest = self.memory.location(new);
        let Some(new_scan) = newest.scan.as_ref() else {
            return Ok(());
        };
        let this = proximity::Candidate {
            id: new,
            stamp_ns: newest.stamp_ns,
            map_from_base: planar_pose(&self.graph, newest),
        };
        let older = self.memory.locations()[..new as usize]
            .iter()
            .filter(|l| l.scan.is_some())
            .map(|l| proximity::Candidate {
                id: l.id,
                stamp_ns: l.stamp_ns,
                map_from_base: planar_pose(&self.graph, l),
            });
        let Some(old) = proximity::nearest(&this, older, &self.cfg.proximity) else {
            return Ok(());
        };
        // The old location's scan with its neighbours', in its frame: one scan holds a
        // trunk or two within range, too few to register on their own.
        let reach = self.cfg.proximity.submap_neighbours as u64;
        let mut old_scan = Vec::new();
        for l in &self.memory.locations()
            [old.id.saturating_sub(reach) as usize..=(old.id + reach).min(new - 1) as usize]
        {
            if let Some(scan) = &l.scan {
                let old_from_l = old.map_from_base.inverse() * planar_pose(&self.graph, l);
                old_scan.extend(
                    self.scan_in_base(scan)
                        .iter()
                        .map(|p| (old_from_l * nalgebra::Point2::from(*p)).coords),
                );
            }
        }
        let new_scan = self.scan_in_base(new_scan);
        let guess = old.map_from_base.inverse() * this.map_from_base;
        let head = format!(
            "location {new} (t_ns={}) with location {} (t_ns={}) by proximity",
            this.stamp_ns, old.id, old.stamp_ns
        );
        match proximity::register(
            &old_scan,
            &new_scan,
            guess,
            &self.cfg.icp.icp,
            &self.cfg.proximity,
        ) {
            Err(why) => {
                self.loop_event(
                    EventKind::LoopClosureRejected,
                    new,
                    old.id,
                    format!("{head}: {why}"),
                );
                Ok(())
            }
            Ok(result) => {
                let sigma_m = (result.rmse_m / (result.inliers.max(1) as f64).sqrt())
                    .max(self.cfg.loop_closure.min_sigma_m);
                let sigmas = Sigmas {
                    rad: self.cfg.loop_closure.min_sigma_rad,
                    m: sigma_m,
                };
                let what = format!(
                    "{head}: ICP matched {:.0}% of the scan, rmse {:.3} m",
                    result.correspondence_ratio * 100.0,
                    result.rmse_m
                );
                // ICP measures x, y and yaw; height, roll and pitch between the two stay
                // as the graph has them.
                let pose = |id: u64| {
                    self.graph
                        .pose(id)
                        .unwrap_or(self.memory.location(id).odom_from_base)
                };
                let estimate = pose(old.id).inverse() * pose(new);
                let (roll, pitch, _) = estimate.rotation.euler_angles();
                let link = raised(
                    &result.target_from_source,
                    estimate.translation.z,
                    roll,
                    pitch,
                );
                self.add_loop_link(old.id, new, link, sigmas, &what)
            }
        }
    }

    /// A scan's points (sensor frame, in scan order) that the odometry would register (on
    /// narrow objects, within the ICP range), in the base frame, planar.
    pub(super) fn scan_in_base(&self, scan: &[Vector2<f64>]) -> Vec<Vector2<f64>> {
        let base_from_scan = planar(&self.base_from_scan);
        let max = if self.cfg.icp.max_range_m > 0.0 {
            self.cfg.icp.max_range_m
        } else {
            f64::INFINITY
        };
        scan.iter()
            .zip(narrow_returns(scan, &self.cfg.icp))
            .filter(|(p, narrow)| *narrow && p.norm() <= max)
            .map(|(p, _)| (base_from_scan * nalgebra::Point2::from(*p)).coords)
            .collect()
    }

    /// A loop link's standard deviations from how well the inliers fit: the median
    /// reprojection error in pixels, scaled to metres at the inliers' median depth, and to
    /// radians by the focal length; floored by the configured minimums.
    fn loop_sigmas(
        &self,
        object: &[Vector3<f64>],
        pixels: &[[f32; 2]],
        result: &pnp::PnpResult,
    ) -> Sigmas {
        let [fx, fy, cx, cy] = self.intrinsics;
        let mut errors: Vec<f64> = Vec::with_capacity(result.inliers.len());
        let mut depths: Vec<f64> = Vec::with_capacity(result.inliers.len());
        for &i in &result.inliers {
            let p = result.camera_from_object * Point3::from(object[i]);
            let (u, v) = (fx * p.x / p.z + cx, fy * p.y / p.z + cy);
            errors.push(
                ((u - f64::from(pixels[i][0])).powi(2) + (v - f64::from(pixels[i][1])).powi(2))
                    .sqrt(),
            );
            depths.push(p.z);
        }
        let median = |v: &mut Vec<f64>| {
            v.sort_by(f64::total_cmp);
            v.get(v.len() / 2).copied().unwrap_or(0.0)
        };
        let (e, z) = (median(&mut errors), median(&mut depths));
        let f = 0.5 * (fx + fy);
        Sigmas {
            rad: (e / f).max(self.cfg.loop_closure.min_sigma_rad),
            m: (e * z / f).max(self.cfg.loop_closure.min_sigma_m),
        }
    }
}
