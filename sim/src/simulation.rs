//! A simulation run: the world, the scenario's route and trajectory, and the ray caster,
//! from which any selection of sensors can be streamed.

use std::str::FromStr;

use crate::camera::RgbdCamera;
use crate::config::{RaycasterKind, SensorsConfig, Side, SimConfig};
use crate::error::SimError;
use crate::raycast::{Bvh, ParryCaster, RayCaster};
use crate::rng::stream;
use crate::robot::{Route, Trajectory, Vibration, drive};
use crate::sensors::{
    GroundTruthSensor, ImuSensor, LidarSensor, Message, RgbdFrame, RgbdSensor, Scan2dSensor,
    ScanSide, Scene, Sensor, WheelOdometrySensor,
};
use crate::world::World;

/// Which sensors a stream carries.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct SensorSet {
    pub ground_truth: bool,
    pub imu: bool,
    pub wheel_odometry: bool,
    pub lidar: bool,
    pub scan2d: bool,
    pub rgbd: bool,
    /// The GNSS receiver, where the world has one (`sensors.gnss`).
    pub gnss: bool,
}

impl SensorSet {
    pub const ALL: SensorSet = SensorSet {
        ground_truth: true,
        imu: true,
        wheel_odometry: true,
        lidar: true,
        scan2d: true,
        rgbd: true,
        gnss: true,
    };
}

impl FromStr for SensorSet {
    type Err = String;

    /// Parses `gt,imu,odom,lidar,scan2d,rgbd,gnss` (any subset, comma-separated) or `all`.
    fn from_str(s: &str) -> Result<Self, String> {
        let mut set = SensorSet::default();
        for name in s.split(',').map(str::trim).filter(|n| !n.is_empty()) {
            match name {
                "all" => set = SensorSet::ALL,
                "gt" => set.ground_truth = true,
                "imu" => set.imu = true,
                "odom" => set.wheel_odometry = true,
                "lidar" => set.lidar = true,
                "scan2d" => set.scan2d = true,
                "rgbd" => set.rgbd = true,
                "gnss" => set.gnss = true,
                other => {
                    return Err(format!(
                        "unknown sensor '{other}' (known: gt, imu, odom, lidar, scan2d, rgbd, gnss, all)"
                    ));
                }
            }
        }
        Ok(set)
    }
}

/// Everything a run needs, built once.
#[derive(Debug)]
pub struct Simulation {
    /// The configuration: the sensors' mounts as the systems are told them.
    pub config: SimConfig,
    /// The sensors as they really are: each mount moved by its `mount_error`, drawn for
    /// this run's seed (equal to `config.sensors` when every error is zero).
    placed: SensorsConfig,
    pub world: World,
    pub route: Route,
    pub trajectory: Trajectory,
    caster: Box<dyn RayCaster>,
    seed: u64,
}

impl Simulation {
    /// Builds the world and drives the scenario's route. `seed` drives all sensor noise.
    pub fn new(config: &SimConfig, scenario: &str, seed: u64) -> Result<Self, SimError> {
        let world = World::from_config(config);
        Self::with_world(config, world, scenario, seed)
    }

    /// As [`Simulation::new`] on an already built world.
    pub fn with_world(
        config: &SimConfig,
        world: World,
        scenario: &str,
        seed: u64,
    ) -> Result<Self, SimError> {
        let spec = config
            .scenarios
            .get(scenario)
            .ok_or_else(|| SimError::UnknownScenario {
                name: scenario.to_owned(),
                known: config
                    .scenarios
                    .keys()
                    .cloned()
                    .collect::<Vec<_>>()
                    .join(", "),
            })?;
        let route = Route::build(scenario, spec, &config.vineyard)?;
        let samples = drive(&route, &config.robot).ok_or_else(|| SimError::Route {
            name: scenario.to_owned(),
            message: "the controller did not reach the end within an hour of simulated time".into(),
        })?;
        let trajectory = Trajectory::from_samples(&samples, &world.terrain, &config.robot)
            .with_vibration(Vibration::new(
                &config.robot.vibration,
                config.sensors.imu.mount.xyz_m,
                &mut stream(seed, "vibration"),
            ));
        let caster: Box<dyn RayCaster> = match config.raycaster {
            RaycasterKind::Bvh => Box::new(Bvh::build(&world.mesh)),
            RaycasterKind::Parry => Box::new(ParryCaster::build(&world.mesh)),
            #[cfg(feature = "embree")]
            RaycasterKind::Embree => Box::new(
                crate::raycast::EmbreeCaster::build(&world.mesh).map_err(|e| SimError::Config {
                    origin: "raycaster = \"embree\"".into(),
                    message: e.to_string(),
                })?,
            ),
            #[cfg(not(feature = "embree"))]
            RaycasterKind::Embree => {
                return Err(SimError::Config {
                    origin: "raycaster = \"embree\"".into(),
                    message: "this build has no Embree (vinebench-sim's cargo feature `embree` \
                              is off); use \"bvh\" or \"parry\""
                        .into(),
                });
            }
        };
        Ok(Self {
            config: config.clone(),
            placed: placed_sensors(&config.sensors, seed),
            world,
            route,
            trajectory,
            caster,
            seed,
        })
    }

    /// The sensors as they really sit in this run (their mounts moved by the drawn
    /// `mount_error`s); `config.sensors` is what the systems are told.
    pub fn placed_sensors(&self) -> &SensorsConfig {
        &self.placed
    }

    pub fn duration_ns(&self) -> i64 {
        self.trajectory.duration_ns()
    }

    pub fn scene(&self) -> Scene<'_> {
        Scene {
            world: &self.world,
            trajectory: &self.trajectory,
            caster: self.caster.as_ref(),
        }
    }

    /// The camera frame of the stream (`stream` with `rgbd`) whose stamp is the latest at or
    /// before `stamp_ns`, exactly as the stream gives it (the same pose, and the same noise:
    /// frame `k` renders with the `k`-th seed of the camera's stream, which is drawn here
    /// without rendering the frames before it). `None` before the first frame or after the
    /// route. Lets an evaluation show the frames a system was given without keeping them.
    pub fn rgbd_frame_at(&self, stamp_ns: i64) -> Option<RgbdFrame> {
        let rate_hz = self.placed.camera.rate_hz;
        let offset_ns = self.placed.camera.clock_offset_ns;
        let stamp_ns = stamp_ns - offset_ns;
        if stamp_ns < 0 || stamp_ns > self.duration_ns() || rate_hz.is_nan() || rate_hz <= 0.0 {
            return None;
        }
        // The frame index from the stamp, then corrected for the rounding of
        // `sample_time_ns` so that its stamp is the latest at or before `stamp_ns`.
        let mut k = (stamp_ns as f64 * rate_hz / 1e9).floor() as u64;
        while k > 0 && crate::sensors::sample_time_ns(k, rate_hz) > stamp_ns {
            k -= 1;
        }
        while crate::sensors::sample_time_ns(k + 1, rate_hz) <= stamp_ns {
            k += 1;
        }
        let mut rng = stream(self.seed, "rgbd");
        for _ in 0..k {
            let _: u64 = rand::Rng::random(&mut rng);
        }
        let camera = RgbdCamera::new(&self.placed.camera, &self.world);
        let frame_ns = crate::sensors::sample_time_ns(k, rate_hz);
        Some(RgbdFrame {
            stamp_ns: frame_ns + offset_ns,
            image: camera.render(&self.trajectory.pose(frame_ns), &mut rng),
        })
    }

    /// What pixel `(u, v)` of the colour camera (pixel centres at integers, as
    /// [`crate::camera::Intrinsics`] has them) shows in the frame stamped `stamp_ns`: the
    /// first surface on its ray, a fence panel told apart from the trellis posts whose wood
    /// it shares; `None` where the ray meets nothing (sky or background). Lets an
    /// evaluation say what a system's matched keypoints lay on.
    pub fn surface_at_pixel(&self, stamp_ns: i64, u: f64, v: f64) -> Option<Surface> {
        let cfg = &self.placed.camera;
        let intrinsics = crate::camera::Intrinsics::from_config(cfg);
        let world_from_optical = self.trajectory.pose(stamp_ns - cfg.clock_offset_ns)
            * cfg.mount.base_from_sensor()
            * crate::camera::camera_from_optical();
        let [x, y, z] = intrinsics.ray(u, v);
        let dir = (world_from_optical.rotation * nalgebra::Vector3::new(x, y, z)).normalize();
        let origin = nalgebra::Point3::from(world_from_optical.translation.vector.cast::<f32>());
        let hit = self
            .caster
            .cast(&origin, &dir.cast::<f32>(), 0.0, f32::MAX)?;
        let triangle = hit.triangle as usize;
        Some(if self.world.fence_triangles.contains(&triangle) {
            Surface::Fence
        } else {
            Surface::Material(self.world.mesh.materials[triangle])
        })
    }

    /// The lidar sweep of the stream whose stamp is the latest at or before `stamp_ns`,
    /// with the stream's geometry (every column from the pose at its own firing time) but
    /// without its range noise (σ of a few cm, drawn in order from the route's start, so
    /// that the stream's own would mean casting every sweep before): a picture of what the
    /// sensor saw there, not the bytes a system was given. Points in the lidar frame, as
    /// in the stream. `None` before the first complete sweep or after the route.
    pub fn lidar_sweep_at(&self, stamp_ns: i64) -> Option<crate::sensors::LidarScan> {
        let mut cfg = self.placed.lidar.clone();
        cfg.noise = crate::config::NoiseProfile::None;
        let mut lidar = LidarSensor::new(&cfg, self.duration_ns(), stream(self.seed, "lidar"));
        let stamp_ns = stamp_ns - cfg.clock_offset_ns;
        if stamp_ns < 0 || lidar.sweep_ns() <= 0 {
            return None;
        }
        lidar.start_at((stamp_ns / lidar.sweep_ns()) as u64);
        lidar.next_ready_ns()?;
        match lidar.emit(&self.scene()) {
            Message::Lidar(mut scan) => {
                scan.stamp_ns += cfg.clock_offset_ns;
                Some(scan)
            }
            _ => None,
        }
    }

    /// The time-ordered message stream of the selected sensors.
    pub fn stream(&self, sensors: SensorSet) -> Stream<'_> {
        let s = &self.placed;
        let end = self.duration_ns();
        let rng = |tag: &str| stream(self.seed, tag);
        let mut list: Vec<Box<dyn Sensor>> = Vec::new();
        if sensors.ground_truth {
            list.push(Box::new(GroundTruthSensor::new(
                s.ground_truth.rate_hz,
                end,
            )));
        }
        if sensors.imu {
            list.push(Box::new(ImuSensor::new(&s.imu, end, rng("imu"))));
        }
        if sensors.wheel_odometry {
            list.push(on_clock(
                Box::new(WheelOdometrySensor::new(
                    &s.wheel_odometry,
                    end,
                    rng("odom"),
                )),
                s.wheel_odometry.clock_offset_ns,
            ));
        }
        if sensors.scan2d {
            for (cfg, side, tag) in [
                (&s.scan2d_front, ScanSide::Front, "scan_front"),
                (&s.scan2d_back, ScanSide::Back, "scan_back"),
            ] {
                list.push(on_clock(
                    Box::new(Scan2dSensor::new(cfg, side, end, rng(tag))),
                    cfg.clock_offset_ns,
                ));
            }
        }
        if sensors.lidar {
            list.push(on_clock(
                Box::new(LidarSensor::new(&s.lidar, end, rng("lidar"))),
                s.lidar.clock_offset_ns,
            ));
        }
        if sensors.rgbd {
            let camera = RgbdCamera::new(&s.camera, &self.world);
            list.push(on_clock(
                Box::new(RgbdSensor::new(camera, end, rng("rgbd"))),
                s.camera.clock_offset_ns,
            ));
        }
        if sensors.gnss && !s.gnss.is_absent() {
            list.push(Box::new(crate::sensors::gnss::GnssSensor::new(
                &s.gnss,
                end,
                rng("gnss"),
            )));
        }
        Stream {
            scene: self.scene(),
            sensors: list,
        }
    }
}

/// A sensor on a clock of its own (`clock_offset_ns`): each message stamped and available
/// `offset_ns` after the measurement.
#[derive(Debug)]
struct Late {
    sensor: Box<dyn Sensor>,
    offset_ns: i64,
}

impl Sensor for Late {
    fn next_ready_ns(&self) -> Option<i64> {
        self.sensor.next_ready_ns().map(|t| t + self.offset_ns)
    }

    fn emit(&mut self, scene: &Scene<'_>) -> Message {
        let mut message = self.sensor.emit(scene);
        message.shift_stamp(self.offset_ns);
        message
    }
}

/// `sensor` as it is, or on a clock `offset_ns` late.
fn on_clock(sensor: Box<dyn Sensor>, offset_ns: i64) -> Box<dyn Sensor> {
    match offset_ns {
        0 => sensor,
        _ => Box::new(Late { sensor, offset_ns }),
    }
}

/// What a camera pixel shows ([`Simulation::surface_at_pixel`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord)]
pub enum Surface {
    /// A panel of the fence around the block.
    Fence,
    Material(crate::world::Material),
}

impl Surface {
    pub fn name(self) -> &'static str {
        match self {
            Self::Fence => "fence",
            Self::Material(m) => m.name(),
        }
    }
}

/// Messages of several sensors merged in the order they become available (a lidar sweep at
/// its end, everything else at its stamp); ties go to the sensor listed first (ground
/// truth, IMU, odometry, 2D scans, lidar, camera). Lazy: one message is made per `next`.
#[derive(Debug)]
pub struct Stream<'a> {
    scene: Scene<'a>,
    sensors: Vec<Box<dyn Sensor>>,
}

impl Iterator for Stream<'_> {
    type Item = Message;

    fn next(&mut self) -> Option<Message> {
        let (index, _) = self
            .sensors
            .iter()
            .enumerate()
            .filter_map(|(i, s)| s.next_ready_ns().map(|t| (i, t)))
            .min_by_key(|&(i, t)| (t, i))?;
        Some(self.sensors[index].emit(&self.scene))
    }
}

/// `sensors` with every mount moved by its error drawn under `seed`, each sensor from a
/// stream of its own.
fn placed_sensors(sensors: &SensorsConfig, seed: u64) -> SensorsConfig {
    let mut placed = sensors.clone();
    let s = sensors;
    placed.imu.mount = s.imu.mount_error.place(s.imu.mount, seed, "imu");
    placed.lidar.mount = s.lidar.mount_error.place(s.lidar.mount, seed, "lidar");
    placed.camera.mount = s.camera.mount_error.place(s.camera.mount, seed, "rgbd");
    for (side, scanner, tag) in [
        (Side::Front, &mut placed.scan2d_front, "scan_front"),
        (Side::Back, &mut placed.scan2d_back, "scan_back"),
    ] {
        if !scanner.mount_error.is_zero() {
            let nominal = scanner.mount_for(side);
            scanner.mount = Some(scanner.mount_error.place(nominal, seed, tag));
        }
    }
    placed
}
