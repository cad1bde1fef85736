//! The plugin: odometry between messages, a location per second, loop closure and the graph.

use nalgebra::{Isometry3, Point3, UnitQuaternion, Vector2, Vector3};
use plugin_api::{
    Event, EventKind, Imu, LaserScan, OccupancyGrid, PluginError, Pose, Requirements, RgbdFrame,
    Rig, SensorKind, SlamOutput, SlamSystem, WheelOdometry,
};
use slam_common::occupancy::OccupancyGridBuilder;
use slam_common::scan2d::points_from_ranges;

use crate::config::{Config, OdometrySource};
use crate::features::{Features, Image, extract};
use crate::graph::{LinkKind, LoopOutcome, PoseGraph, Sigmas, Strain};
use crate::memory::{Hypothesis, Location, Memory, Update};
use crate::pnp::{self, PnpConfig};
use crate::proximity;
use crate::scan_odometry::{ScanOdometry, Sweep, narrow_returns, planar, raised, spatial};
use crate::visual_odometry::{Tracking, VisualOdometry};

/// The odometry the configuration chose. One per plugin instance, made once and never
/// moved: the variants' sizes do not matter.
#[derive(Debug)]
#[allow(clippy::large_enum_variant)]
enum Odometry {
    Visual(Option<VisualOdometry>),
    WheelIcp(ScanOdometry),
}

/// An odometry pose and the location it followed, so that the final trajectory moves with
/// the optimised locations.
#[derive(Debug, Clone, Copy)]
struct Record {
    stamp_ns: i64,
    odom_from_base: Isometry3<f64>,
    location: Option<u64>,
}

/// A location's update and the time of the camera frame that made it (`locations_csv`).
#[derive(Debug, Clone, Copy)]
struct LocationTiming {
    id: u64,
    stamp_ns: i64,
    update: Update,
    step_ns: u128,
    /// CPU time of the thread over the same frame, if the system says (Linux), which unlike
    /// the wall time does not grow when other processes share the cores.
    step_cpu_ns: Option<u64>,
}

/// CPU time this thread has run, ns (Linux: the first field of `/proc/thread-self/schedstat`).
fn thread_cpu_ns() -> Option<u64> {
    std::fs::read_to_string("/proc/thread-self/schedstat")
        .ok()?
        .split_whitespace()
        .next()?
        .parse()
        .ok()
}

/// RTAB-Map-style appearance-based RGB-D SLAM.
#[derive(Debug)]
pub struct Rtabmap {
    cfg: Config,
    base_from_camera: Isometry3<f64>,
    base_from_scan: Isometry3<f64>,
    /// The IMU's orientation on the base, to read the gyro's yaw rate.
    base_r_imu: UnitQuaternion<f64>,
    /// The camera's `[fx, fy, cx, cy]`, from the rig.
    intrinsics: [f64; 4],
    odometry: Odometry,
    /// The newest scan of `cfg.scan`: its stamp and points in its frame.
    latest_scan: Option<(i64, Vec<Vector2<f64>>)>,
    memory: Memory,
    graph: PoseGraph,
    records: Vec<Record>,
    events: Vec<Event>,
    /// Odometry was lost since the last location: the link to the next one is a guess.
    lost_since_location: bool,
    /// Every location's update, kept when `locations_csv` is set.
    location_timings: Vec<LocationTiming>,
}

/// Frames older than this do not lend their scan to a location, ns.
const SCAN_MAX_AGE_NS: i64 = 100_000_000;

impl Rtabmap {
    fn error(what: &str) -> impl Fn(String) -> PluginError + '_ {
        move |e| PluginError::new(format!("{what}: {e}"))
    }

    /// `map_from_odom` as the graph last corrected it.
    fn map_from_odom(&self) -> Isometry3<f64> {
        match self.memory.last() {
            Some(l) => {
                self.graph.pose(l.id).unwrap_or(l.odom_from_base) * l.odom_from_base.inverse()
            }
            None => Isometry3::identity(),
        }
    }

    /// Records an odometry pose; returns it in the map frame.
    fn record(&mut self, stamp_ns: i64, odom_from_base: Isometry3<f64>) -> Pose {
        self.records.push(Record {
            stamp_ns,
            odom_from_base,
            location: self.memory.last().map(|l| l.id),
        });
        Pose::new(stamp_ns, &(self.map_from_odom() * odom_from_base))
    }

    fn event(&mut self, stamp_ns: i64, kind: EventKind, detail: String) {
        self.events.push(Event::new(stamp_ns, kind, detail));
    }

    /// A loop closure between location `new` and the older `old`, at `new`'s stamp.
    fn loop_event(&mut self, kind: EventKind, new: u64, old: u64, detail: String) {
        let (new_ns, old_ns) = (
            self.memory.location(new).stamp_ns,
            self.memory.location(old).stamp_ns,
        );
        self.events
            .push(Event::loop_closure(new_ns, kind, [new_ns, old_ns], detail));
    }

    /// Whether a new location is due: a detection period since the last one, and moved.
    fn location_due(&self, stamp_ns: i64, odom_from_base: &Isometry3<f64>) -> bool {
        let Some(last) = self.memory.last() else {
            return true;
        };
        let period_ns = (1e9 / self.cfg.memory.detection_rate_hz) as i64;
        // Half a camera period of slack, so that 30 Hz frames give 1 Hz and not 0.97 Hz.
        if stamp_ns - last.stamp_ns < period_ns - 16_000_000 {
            return false;
        }
        let moved = last.odom_from_base.inverse() * odom_from_base;
        moved.translation.vector.norm() >= self.cfg.memory.linear_update_m
            || moved.rotation.angle() >= self.cfg.memory.angular_update_rad
    }

    /// Decimated depth points of a frame in the base frame.
    fn cloud(&self, image: &Image<'_>) -> Vec<Vector3<f32>> {
        let step = self.cfg.map_decimation;
        let [fx, fy, cx, cy] = image.intrinsics;
        let mut out = Vec::new();
        for v in (0..image.height).step_by(step) {
            for u in (0..image.width).step_by(step) {
                let z = f64::from(image.depth_m[v * image.width + u]);
                if !(z.is_finite()
                    && z >= self.cfg.features.min_depth_m
                    && z <= self.cfg.features.max_depth_m)
                {
                    continue;
                }
                let p = Point3::new(z * (u as f64 - cx) / fx, z * (v as f64 - cy) / fy, z);
                out.push((self.base_from_camera * p).coords.cast::<f32>());
            }
        }
        out
    }

    /// Makes a location at this frame, links it, and looks for a loop closure. Returns the
    /// memory's update.
    fn add_location(
        &mut self,
        stamp_ns: i64,
        odom_from_base: Isometry3<f64>,
        features: Features,
        cloud: Vec<Vector3<f32>>,
    ) -> Result<Update, PluginError> {
        let id = self.memory.next_id();
        let scan = self
            .latest_scan
            .as_ref()
            .filter(|(t, _)| (stamp_ns - t).abs() <= SCAN_MAX_AGE_NS)
            .map(|(_, points)| points.clone());
        let previous = self.memory.last().map(|l| (l.id, l.odom_from_base));
        match previous {
            None => self.graph.add_first(id, odom_from_base),
            Some((prev, prev_odom)) => {
                let link = prev_odom.inverse() * odom_from_base;
                let s = &self.cfg.odometry_link;
                let d = link.translation.vector.norm();
                let scale = if self.lost_since_location { 10.0 } else { 1.0 };
                let sigmas = Sigmas {
                    rad: scale * (s.rad_floor + s.rad_per_m * d),
                    m: scale * (s.m_floor + s.m_per_m * d),
                };
                self.graph.add_odometry(prev, id, link, sigmas)
            }
        }
        .map_err(|e| Self::error("factor graph")(e.to_string()))?;
        self.lost_since_location = false;
        let location = Location {
            id,
            stamp_ns,
            odom_from_base,
            features: features.truncated(self.cfg.memory.max_words),
            words: Vec::new(),
            scan,
            cloud,
        };
        let (_, hypothesis, update) = self.memory.add(location, self.cfg.loop_closure.enabled);
        if let Some(h) = hypothesis {
            self.close_loop(id, h)?;
        }
        if self.cfg.proximity.enabled {
            self.close_by_proximity(id)?;
        }
        Ok(update)
    }

    /// The `locations_csv` table.
    fn locations_csv(&self) -> String {
        let mut out = String::from(
            "location,stamp_ns,descriptors,new_words,vocabulary_words,comparisons,transferred,working_memory,step_ns,step_cpu_ns\n",
        );
        for t in &self.location_timings {
            let u = &t.update;
            out.push_str(&format!(
                "{},{},{},{},{},{},{},{},{},{}\n",
                t.id,
                t.stamp_ns,
                u.descriptors,
                u.new_words,
                u.vocabulary_words,
                u.comparisons,
                u.transferred,
                u.working_memory,
                t.step_ns,
                t.step_cpu_ns.map_or(String::new(), |ns| ns.to_string())
            ));
        }
        out
    }

    /// Verifies a hypothesis by PnP and, if it holds, adds it to the graph, where the
    /// optimisation check may still reject it.
    fn close_loop(&mut self, new: u64, h: Hypothesis) -> Result<(), PluginError> {
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
    fn close_by_proximity(&mut self, new: u64) -> Result<(), PluginError> {
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
    fn scan_in_base(&self, scan: &[Vector2<f64>]) -> Vec<Vector2<f64>> {
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

impl SlamSystem for Rtabmap {
    const NAME: &'static str = "rtabmap";
    const VERSION: &'static str = env!("CARGO_PKG_VERSION");

    fn requirements() -> Requirements {
        Requirements::online(&[
            SensorKind::Rgbd,
            SensorKind::WheelOdometry,
            SensorKind::Scan2d,
            SensorKind::Imu,
        ])
    }

    fn new(config_toml: &str, rig: &Rig) -> Result<Self, PluginError> {
        let cfg = Config::from_toml(config_toml).map_err(PluginError::new)?;
        let camera = rig
            .sensor(&cfg.camera)
            .filter(|s| s.kind == SensorKind::Rgbd)
            .ok_or_else(|| {
                PluginError::new(format!(
                    "the rig has no RGB-D camera called {:?}",
                    cfg.camera
                ))
            })?;
        let scan = rig
            .sensor(&cfg.scan)
            .filter(|s| s.kind == SensorKind::Scan2d)
            .ok_or_else(|| {
                PluginError::new(format!("the rig has no 2D scan called {:?}", cfg.scan))
            })?;
        let k = |key: &str| {
            camera
                .intrinsics
                .get(key)
                .copied()
                .filter(|v| v.is_finite() && *v > 0.0)
                .ok_or_else(|| {
                    PluginError::new(format!("the camera's intrinsics lack a positive {key}"))
                })
        };
        let intrinsics = [k("fx")?, k("fy")?, k("cx")?, k("cy")?];
        let size = (k("width")? as usize, k("height")? as usize);
        let base_from_camera = camera.base_from_sensor();
        let base_from_scan = scan.base_from_sensor();
        let base_r_imu = rig
            .first(SensorKind::Imu)
            .map(|imu| imu.base_from_sensor().rotation)
            .unwrap_or_default();
        let odometry = match cfg.odometry {
            OdometrySource::Visual => Odometry::Visual(Some(VisualOdometry::new(
                cfg.visual.clone(),
                intrinsics,
                size.0,
                size.1,
                base_from_camera,
            ))),
            OdometrySource::WheelIcp => {
                Odometry::WheelIcp(ScanOdometry::new(cfg.icp.clone(), &base_from_scan))
            }
        };
        let graph = PoseGraph::new(&cfg.backend, cfg.loop_closure.optimize_max_error)
            .map_err(|e| PluginError::new(format!("backend: {e}")))?;
        Ok(Self {
            memory: Memory::new(&cfg.memory, &cfg.loop_closure),
            base_from_camera,
            base_from_scan,
            base_r_imu,
            intrinsics,
            odometry,
            latest_scan: None,
            graph,
            records: Vec::new(),
            events: Vec::new(),
            lost_since_location: false,
            location_timings: Vec::new(),
            cfg,
        })
    }

    fn on_imu(&mut self, imu: &Imu) -> Result<Option<Pose>, PluginError> {
        if let Odometry::WheelIcp(scan_odometry) = &mut self.odometry {
            scan_odometry.on_imu(
                imu.stamp_ns,
                &(self.base_r_imu * Vector3::from(imu.gyro_rps)),
                &(self.base_r_imu * Vector3::from(imu.accel_mps2)),
            );
        }
        Ok(None)
    }

    fn on_wheel_odometry(&mut self, odom: &WheelOdometry) -> Result<Option<Pose>, PluginError> {
        if let Odometry::WheelIcp(scan_odometry) = &mut self.odometry {
            scan_odometry.on_wheels(odom.stamp_ns, odom.linear_mps, odom.angular_rps);
        }
        Ok(None)
    }

    fn on_laser_scan(&mut self, scan: &LaserScan<'_>) -> Result<Option<Pose>, PluginError> {
        if scan.sensor != self.cfg.scan {
            return Ok(None);
        }
        let points = points_from_ranges(
            f64::from(scan.angle_min_rad),
            f64::from(scan.angle_increment_rad),
            scan.ranges_m,
            f64::from(scan.range_min_m),
            f64::from(scan.range_max_m),
        );
        let pose = match &mut self.odometry {
            Odometry::WheelIcp(o) => o
                .on_timed_scan(
                    scan.stamp_ns,
                    &points,
                    self.cfg.icp.deskew.then_some(&Sweep {
                        angle_min_rad: f64::from(scan.angle_min_rad),
                        angle_increment_rad: f64::from(scan.angle_increment_rad),
                        time_increment_s: f64::from(scan.time_increment_s),
                    }),
                )
                .map(|step| o.lift(&step.odom_from_base)),
            Odometry::Visual(_) => None,
        };
        self.latest_scan = Some((scan.stamp_ns, points));
        Ok(pose.map(|p| self.record(scan.stamp_ns, p)))
    }

    fn on_rgbd(&mut self, frame: &RgbdFrame<'_>) -> Result<Option<Pose>, PluginError> {
        if frame.sensor != self.cfg.camera {
            return Ok(None);
        }
        let start = std::time::Instant::now();
        let start_cpu = self
            .cfg
            .locations_csv
            .as_ref()
            .and_then(|_| thread_cpu_ns());
        let image = Image {
            width: frame.width as usize,
            height: frame.height as usize,
            rgb: frame.rgb,
            depth_m: frame.depth_m,
            intrinsics: frame.intrinsics,
        };
        let stamp = frame.stamp_ns;
        let (odom_from_base, features, online) = match &mut self.odometry {
            Odometry::Visual(vo) => {
                let features = extract(&image, &self.cfg.features)
                    .map_err(|e| PluginError::new(e.to_string()))?;
                let vo = vo.as_mut().expect("visual odometry");
                let tracking = vo
                    .process(stamp, &features)
                    .map_err(|e| PluginError::new(format!("OpenCV: {e}")))?;
                let camera_from_base = self.base_from_camera.inverse();
                match tracking {
                    Tracking::Ok {
                        odom_from_camera, ..
                    }
                    | Tracking::Started { odom_from_camera } => {
                        if self.lost_since_location && matches!(tracking, Tracking::Ok { .. }) {
                            // Recovered: said once, at the first tracked frame.
                        }
                        (odom_from_camera * camera_from_base, Some(features), true)
                    }
                    Tracking::Lost {
                        guess,
                        inliers,
                        reset,
                    } => {
                        if !self.lost_since_location {
                            self.event(
                                stamp,
                                EventKind::TrackingLost,
                                format!(
                                    "visual odometry: {inliers} PnP inliers (need {}){}",
                                    self.cfg.visual.min_inliers,
                                    if reset { "; map reset" } else { "" }
                                ),
                            );
                        }
                        self.lost_since_location = true;
                        (guess * camera_from_base, None, false)
                    }
                }
            }
            Odometry::WheelIcp(o) => match o.pose_at(stamp) {
                Some(p) => (o.lift(&p), None, false),
                None => return Ok(None),
            },
        };
        let pose = online.then(|| self.record(stamp, odom_from_base));
        if self.location_due(stamp, &odom_from_base)
            && (features.is_some() || matches!(self.odometry, Odometry::WheelIcp(_)))
        {
            let features = match features {
                Some(f) => f,
                None => extract(&image, &self.cfg.features)
                    .map_err(|e| PluginError::new(e.to_string()))?,
            };
            let cloud = self.cloud(&image);
            let id = self.memory.next_id();
            let update = self.add_location(stamp, odom_from_base, features, cloud)?;
            if self.cfg.locations_csv.is_some() {
                self.location_timings.push(LocationTiming {
                    id,
                    stamp_ns: stamp,
                    update,
                    step_ns: start.elapsed().as_nanos(),
                    step_cpu_ns: start_cpu
                        .zip(thread_cpu_ns())
                        .map(|(a, b)| b.saturating_sub(a)),
                });
            }
        }
        Ok(pose)
    }

    fn finish(&mut self) -> Result<SlamOutput, PluginError> {
        if let Some(path) = &self.cfg.profile_csv {
            self.graph
                .backend
                .write_csv(path)
                .map_err(|e| PluginError::new(format!("profile_csv {}: {e}", path.display())))?;
        }
        if let Some(path) = &self.cfg.locations_csv {
            std::fs::write(path, self.locations_csv())
                .map_err(|e| PluginError::new(format!("locations_csv {}: {e}", path.display())))?;
        }
        let trajectory = self
            .records
            .iter()
            .map(|r| {
                let map_from_odom = match r.location {
                    Some(id) => {
                        let l = self.memory.location(id);
                        self.graph.pose(id).unwrap_or(l.odom_from_base) * l.odom_from_base.inverse()
                    }
                    None => Isometry3::identity(),
                };
                Pose::new(r.stamp_ns, &(map_from_odom * r.odom_from_base))
            })
            .collect();
        let mut points = Vec::new();
        let mut grid = OccupancyGridBuilder::new(self.cfg.grid.clone())
            .map_err(|e| PluginError::new(format!("grid: {e}")))?;
        for l in self.memory.locations() {
            let map_from_base = self.graph.pose(l.id).unwrap_or(l.odom_from_base);
            points.extend(
                l.cloud
                    .iter()
                    .map(|p| (map_from_base * Point3::from(p.cast::<f64>())).coords),
            );
            if let Some(scan) = &l.scan {
                grid.insert_scan(&planar(&(map_from_base * self.base_from_scan)), scan, &[]);
            }
        }
        let map = slam_common::voxel::downsample(&points, self.cfg.map_voxel_m)
            .into_iter()
            .map(|p| [p.x as f32, p.y as f32, p.z as f32])
            .collect();
        let g = grid.build();
        Ok(SlamOutput {
            trajectory,
            map: Some(map),
            grid: Some(OccupancyGrid {
                resolution_m: g.resolution_m,
                origin: g.origin,
                width: g.width,
                height: g.height,
                cells: g.cells,
            }),
            events: std::mem::take(&mut self.events),
        })
    }
}
