//! The plugin: odometry between messages, a location per second, loop closure and the graph.

mod localization;
mod location_log;
mod loop_closure;
#[cfg(test)]
mod tests;

use nalgebra::{Isometry3, Point3, UnitQuaternion, Vector2, Vector3};
use plugin_api::{
    Event, EventKind, Gnss as GnssMessage, Imu, LaserScan, MapStart, OccupancyGrid, Parameters,
    PluginError, Pose, PoseStatus, Requirements, RgbdFrame, Rig, SensorKind, SlamOutput,
    SlamSystem, WheelOdometry,
};
use slam_common::maps::occupancy::OccupancyGridBuilder;
use slam_common::registration::scan2d::points_from_ranges;

use crate::config::{Config, OdometrySource};
use crate::features::{Features, Image, extract};
use crate::gps::{Gps, GpsPriors, root_sigmas};
use crate::graph::{PoseGraph, Sigmas};
use crate::memory::{Location, Memory, Update};
use crate::scan_odometry::{ScanOdometry, Sweep, planar};
use crate::visual_odometry::{Tracking, VisualOdometry};
use location_log::{LocationLog, StepStart};

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
    /// A lens's raw frames are rectified first (`Rtabmap/ImagesAlreadyRectified = false`).
    rectifier: Option<crate::rectify::Rectifier>,
    odometry: Odometry,
    /// The newest scan of `cfg.scan`: its stamp and points in its frame.
    latest_scan: Option<(i64, Vec<Vector2<f64>>)>,
    memory: Memory,
    graph: PoseGraph,
    records: Vec<Record>,
    events: Vec<Event>,
    /// Odometry was lost since the last location: the link to the next one is a guess.
    lost_since_location: bool,
    /// Visual odometry is lost now (its recovery is an event).
    odometry_lost: bool,
    /// Every location's update, kept when `locations_csv` is set.
    location_log: Option<LocationLog>,
    /// Localisation mode (`vinebench localize`): the loaded map's state, and the poses
    /// returned.
    localizing: Option<localization::Localizing>,
    localized_trajectory: Vec<Pose>,
    /// GPS priors (`Optimizer/PriorsIgnored = false` and a receiver in the rig): the fixes
    /// and the one every location took (`crate::gps`).
    gps: Option<GpsPriors>,
}

/// Odometry at a camera frame.
#[derive(Debug)]
struct OdometryStep {
    odom_from_base: Isometry3<f64>,
    /// The frame's features, when visual odometry tracked it.
    features: Option<Features>,
    /// An online estimate (not a lost guess).
    online: bool,
}

/// Frames older than this do not lend their scan to a location, ns.
const SCAN_MAX_AGE_NS: i64 = 100_000_000;

impl Rtabmap {
    fn error(what: &str) -> impl Fn(String) -> PluginError + '_ {
        move |e| PluginError::new(format!("{what}: {e}"))
    }

    /// `map_from_odom` as the graph last corrected it (localising: as the last match set it).
    fn map_from_odom(&self) -> Isometry3<f64> {
        if let Some(l) = &self.localizing {
            return l.map_from_odom();
        }
        match self.memory.last() {
            Some(l) => {
                self.graph.pose(l.id).unwrap_or(l.odom_from_base) * l.odom_from_base.inverse()
            }
            None => Isometry3::identity(),
        }
    }

    /// Records an odometry pose; returns it in the map frame.
    fn record(&mut self, stamp_ns: i64, odom_from_base: Isometry3<f64>) -> Pose {
        let pose = Pose::new(stamp_ns, &(self.map_from_odom() * odom_from_base));
        if self.localizing.is_some() {
            self.localized_trajectory.push(pose);
            return pose;
        }
        self.records.push(Record {
            stamp_ns,
            odom_from_base,
            location: self.memory.last().map(|l| l.id),
        });
        pose
    }

    /// Planar odometry (wheels and ICP without attitude), RTAB-Map's `Reg/Force3DoF`: the
    /// graph stays level.
    fn planar(&self) -> bool {
        self.cfg.odometry == OdometrySource::WheelIcp && self.cfg.icp.attitude_gain == 0.0
    }

    /// Puts the GPS prior of each location that has chosen its fix into the graph, which
    /// is then optimised in full (`crate::gps`).
    fn add_gps_priors(&mut self, settled: Vec<(u64, Gps)>) -> Result<(), PluginError> {
        let planar = self.planar();
        for (id, fix) in settled {
            let (Some(gps), Some(map_from_base), Some(location)) = (
                &mut self.gps,
                self.graph.pose(id),
                self.memory.locations().get(id as usize),
            ) else {
                continue;
            };
            let odom_from_base = location.odom_from_base;
            let prior = gps.prior(id, &fix, &map_from_base, &odom_from_base, planar);
            self.graph
                .add_position_prior(id, prior.position, prior.sigmas, root_sigmas(planar))
                .map_err(|e| Self::error("factor graph")(e.to_string()))?;
        }
        Ok(())
    }

    fn event(&mut self, stamp_ns: i64, kind: EventKind, detail: String) {
        self.events.push(Event::new(stamp_ns, kind, detail));
    }

    /// Odometry at a camera frame; `None`: wheel odometry has no pose yet.
    fn odometry_step(
        &mut self,
        stamp: i64,
        image: &Image<'_>,
    ) -> Result<Option<OdometryStep>, PluginError> {
        let vo = match &mut self.odometry {
            Odometry::Visual(vo) => vo.as_mut().expect("visual odometry"),
            Odometry::WheelIcp(o) => {
                return Ok(o.pose_at(stamp).map(|p| OdometryStep {
                    odom_from_base: o.lift(&p),
                    features: None,
                    online: false,
                }));
            }
        };
        let features =
            extract(image, &self.cfg.features).map_err(|e| PluginError::new(e.to_string()))?;
        let tracking = vo
            .process(stamp, &features)
            .map_err(|e| PluginError::new(format!("OpenCV: {e}")))?;
        let camera_from_base = self.base_from_camera.inverse();
        let (odom_from_base, features, online) = match tracking {
            Tracking::Ok {
                odom_from_camera,
                inliers,
                features: n,
                ..
            } => {
                if self.odometry_lost {
                    self.odometry_lost = false;
                    let detail = format!("visual odometry: {inliers} PnP inliers of {n} features");
                    self.event(stamp, EventKind::TrackingRecovered, detail);
                }
                (odom_from_camera * camera_from_base, Some(features), true)
            }
            Tracking::Started { odom_from_camera } => {
                (odom_from_camera * camera_from_base, Some(features), true)
            }
            Tracking::Lost {
                guess,
                inliers,
                reset,
            } => {
                if !self.lost_since_location {
                    let detail = format!(
                        "visual odometry: {inliers} PnP inliers (need {}){}",
                        self.cfg.visual.min_inliers,
                        if reset { "; map reset" } else { "" }
                    );
                    self.event(stamp, EventKind::TrackingLost, detail);
                }
                self.lost_since_location = true;
                self.odometry_lost = true;
                (guess * camera_from_base, None, false)
            }
        };
        Ok(Some(OdometryStep {
            odom_from_base,
            features,
            online,
        }))
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
        if let Some(gps) = &mut self.gps {
            // The previous location's fix is chosen now if it was not yet; this one's
            // when a fix stamped at or after it arrives (at once if one has).
            let settled = gps.location(id, stamp_ns);
            self.add_gps_priors(settled)?;
        }
        if let Some(h) = hypothesis {
            self.close_loop(id, h)?;
        }
        if self.cfg.proximity.enabled {
            self.close_by_proximity(id)?;
        }
        Ok(update)
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
        .localizing()
    }

    /// The GNSS receiver too with `Optimizer/PriorsIgnored = false`.
    fn requirements_for(config_toml: &str) -> Result<Requirements, PluginError> {
        let cfg = Config::from_toml(config_toml).map_err(PluginError::new)?;
        let mut requirements = Self::requirements();
        if !cfg.optimizer.priors_ignored {
            requirements.sensors.push(SensorKind::Gnss);
        }
        Ok(requirements)
    }

    /// RTAB-Map's localisation mode in a map a mapping run saved (`system::localization`).
    fn localize(config_toml: &str, rig: &Rig, start: &MapStart<'_>) -> Result<Self, PluginError> {
        if (start.format, start.format_version) != (localization::FORMAT, localization::VERSION) {
            return Err(PluginError::new(format!(
                "rtabmap reads {} version {} maps, not {} version {}",
                localization::FORMAT,
                localization::VERSION,
                start.format,
                start.format_version
            )));
        }
        let mut system = Self::new(config_toml, rig)?;
        // The saved map is the reference: no GPS priors move it.
        system.gps = None;
        system.load_map(start.map)?;
        if let (Some(guess), Some(l)) = (
            start.initial_guess.and_then(|g| g.map_from_base.isometry()),
            &mut system.localizing,
        ) {
            // Odometry starts at the identity: the guess is `map_from_odom`.
            l.guess(guess);
        }
        Ok(system)
    }

    fn status(&self) -> PoseStatus {
        match &self.localizing {
            Some(l) if !l.localized() => PoseStatus::Searching,
            _ => PoseStatus::Localized,
        }
    }

    fn new(config_toml: &str, rig: &Rig) -> Result<Self, PluginError> {
        let cfg = Config::from_toml(config_toml).map_err(PluginError::new)?;
        let camera = rig.require(&cfg.camera, SensorKind::Rgbd)?;
        let scan = rig.require(&cfg.scan, SensorKind::Scan2d)?;
        let pinhole = camera.pinhole()?;
        let intrinsics = pinhole.intrinsics();
        let size = (pinhole.width as usize, pinhole.height as usize);
        let rectifier = match camera.lens()? {
            Some(lens) if !cfg.rtabmap.images_already_rectified => {
                Some(crate::rectify::Rectifier::new(&pinhole, &lens))
            }
            Some(lens) => {
                eprintln!(
                    "rtabmap: the camera reports a lens ({lens:?}) and \
                     Rtabmap/ImagesAlreadyRectified = true (RTAB-Map's default): its raw \
                     images are taken as rectified"
                );
                None
            }
            None => None,
        };
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
        let gps = match (cfg.optimizer.priors_ignored, rig.first(SensorKind::Gnss)) {
            (true, _) => None,
            (false, None) => {
                eprintln!(
                    "rtabmap: Optimizer/PriorsIgnored = false, but the world has no GNSS \
                     receiver: no GPS priors"
                );
                None
            }
            (false, Some(receiver)) => Some(GpsPriors::new(
                receiver.base_from_sensor().translation.vector,
                cfg.memory.detection_rate_hz,
            )),
        };
        Ok(Self {
            memory: Memory::new(&cfg.memory, &cfg.loop_closure),
            base_from_camera,
            base_from_scan,
            base_r_imu,
            intrinsics,
            rectifier,
            odometry,
            latest_scan: None,
            graph,
            records: Vec::new(),
            events: Vec::new(),
            lost_since_location: false,
            odometry_lost: false,
            location_log: cfg.locations_csv.as_ref().map(|_| LocationLog::default()),
            localizing: None,
            localized_trajectory: Vec::new(),
            gps,
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

    /// Keeps a usable fix for the locations' GPS priors, refuses one that cannot be used
    /// with a `gnss_rejected` event (never an error); a fix stamped after the newest
    /// location settles the fix it takes, and its prior goes into the graph. Ignored with
    /// `Optimizer/PriorsIgnored = true`.
    fn on_gnss(&mut self, gnss: &GnssMessage) -> Result<Option<Pose>, PluginError> {
        let Some(gps) = &mut self.gps else {
            return Ok(None);
        };
        let settled = gps.push(gnss, &mut self.events);
        self.add_gps_priors(settled.into_iter().collect())?;
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

    /// RTAB-Map's loop on a camera frame (Labbé and Michaud, JFR 2019, Fig. 1): odometry on
    /// every frame; at the detection rate, a new location whose signature joins working
    /// memory, whose loop-closure hypothesis is verified, and whose scan looks for loops by
    /// proximity, all linked in the graph (`add_location`).
    fn on_rgbd(&mut self, frame: &RgbdFrame<'_>) -> Result<Option<Pose>, PluginError> {
        if frame.sensor != self.cfg.camera {
            return Ok(None);
        }
        let step = self.location_log.as_ref().map(|_| StepStart::now());
        let rectified = self
            .rectifier
            .as_ref()
            .map(|r| r.rectify(frame.rgb, frame.depth_m));
        let (rgb, depth_m) = rectified
            .as_ref()
            .map_or((frame.rgb, frame.depth_m), |(rgb, depth)| {
                (rgb.as_slice(), depth.as_slice())
            });
        let image = Image {
            width: frame.width as usize,
            height: frame.height as usize,
            rgb,
            depth_m,
            intrinsics: frame.intrinsics,
        };
        let stamp = frame.stamp_ns;
        let Some(OdometryStep {
            odom_from_base,
            features,
            online,
        }) = self.odometry_step(stamp, &image)?
        else {
            return Ok(None);
        };
        let pose = online.then(|| self.record(stamp, odom_from_base));
        let can_locate = features.is_some() || matches!(self.odometry, Odometry::WheelIcp(_));
        if self.localizing.is_some() {
            if can_locate && self.detection_due(stamp, &odom_from_base) {
                let features = match features {
                    Some(f) => f,
                    None => extract(&image, &self.cfg.features)
                        .map_err(|e| PluginError::new(e.to_string()))?,
                };
                self.detect_in_map(stamp, odom_from_base, features)?;
            }
            return Ok(pose);
        }
        if can_locate && self.location_due(stamp, &odom_from_base) {
            let features = match features {
                Some(f) => f,
                None => extract(&image, &self.cfg.features)
                    .map_err(|e| PluginError::new(e.to_string()))?,
            };
            let cloud = self.cloud(&image);
            let id = self.memory.next_id();
            let update = self.add_location(stamp, odom_from_base, features, cloud)?;
            if let (Some(log), Some(step)) = (&mut self.location_log, step) {
                log.push(id, stamp, update, step);
            }
        }
        Ok(pose)
    }

    fn finish(&mut self) -> Result<SlamOutput, PluginError> {
        if let Some(l) = &self.localizing {
            eprintln!(
                "rtabmap: localising in {} locations: {} detections, {} matched by appearance, {} by proximity",
                self.memory.locations().len(),
                l.detections,
                l.appearance,
                l.proximity
            );
            return Ok(SlamOutput {
                trajectory: std::mem::take(&mut self.localized_trajectory),
                ..SlamOutput::default()
            });
        }
        if let Some(gps) = &mut self.gps {
            let settled = gps.finish();
            self.add_gps_priors(settled.into_iter().collect())?;
        }
        if let Some(gps) = &self.gps {
            eprintln!(
                "rtabmap: GPS priors on {} of {} locations",
                gps.priors(),
                self.memory.locations().len()
            );
        }
        if let Some(path) = &self.cfg.profile_csv {
            self.graph
                .backend
                .write_csv(path)
                .map_err(|e| PluginError::new(format!("profile_csv {}: {e}", path.display())))?;
        }
        if let (Some(path), Some(log)) = (&self.cfg.locations_csv, &self.location_log) {
            std::fs::write(path, log.csv())
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
        let map = slam_common::registration::voxel::downsample(&points, self.cfg.map_voxel_m)
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
            saved_map: Some(self.saved_map()),
        })
    }
}
