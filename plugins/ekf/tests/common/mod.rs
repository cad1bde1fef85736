//! Synthetic runs for the EKF's tests: a robot driving vineyard-like lanes (straight rows
//! joined by U-turns) on flat ground, with wheel odometry, an IMU and GNSS fixes drawn with
//! known noise from a seeded generator, delivered in order of availability as the host
//! delivers them (a fix after its latency, stamped at its epoch).

#![allow(dead_code)]

use std::collections::BTreeMap;
use std::f64::consts::{FRAC_PI_2, PI};

use ekf::EkfLocalization;
use nalgebra::{Isometry3, Translation3, UnitQuaternion, Vector3};
use plugin_api::{
    Gnss, GnssStatus, Imu, Pose, Rig, SensorKind, SensorSpec, SlamOutput, SlamSystem, WheelOdometry,
};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, StandardNormal};

/// Where the robot starts in the datum's east-north-up frame, and its heading.
pub const START_ENU: [f64; 2] = [20.0, -8.0];
pub const START_HEADING: f64 = 0.6;
/// The antenna in the base frame: behind, left, and 1.7 m up.
pub const LEVER_ARM: [f64; 3] = [-0.3, 0.1, 1.7];
const GRAVITY: f64 = 9.80665;
const TRUTH_DT_NS: i64 = 1_000_000;
const ODOM_PERIOD_NS: i64 = 20_000_000;
const IMU_PERIOD_NS: i64 = 5_000_000;
const TURN_RADIUS_M: f64 = 1.5;

// The rig's datasheet figures (the simulator's defaults), used to draw the noise.
const SLIP_SIGMA: f64 = 0.01;
const SCALE_ERROR: f64 = 0.01;
const YAW_SCALE_ERROR: f64 = 0.02;
const YAW_RATE_NOISE_DENSITY: f64 = 0.002;
const GYRO_NOISE_DENSITY: f64 = 1.7e-4;
const GYRO_BIAS: f64 = 1.0e-3;
const ACCEL_NOISE_DENSITY: f64 = 2.0e-3;

/// The GNSS receiver of a run.
#[derive(Debug, Clone, Copy)]
pub struct GnssSetup {
    /// Horizontal standard deviation of each fix (the vertical one is twice it), m.
    pub sigma_m: f64,
    pub latency_ns: i64,
    pub period_ns: i64,
}

impl Default for GnssSetup {
    fn default() -> Self {
        Self {
            sigma_m: 0.03,
            latency_ns: 50_000_000,
            period_ns: 200_000_000,
        }
    }
}

/// A run to generate.
#[derive(Debug, Clone, Copy)]
pub struct Scenario {
    pub seed: u64,
    pub rows: usize,
    pub row_length_m: f64,
    pub speed_mps: f64,
    pub gnss: Option<GnssSetup>,
    pub reports_orientation: bool,
}

impl Default for Scenario {
    fn default() -> Self {
        Self {
            seed: 7,
            rows: 4,
            row_length_m: 30.0,
            speed_mps: 1.0,
            gnss: Some(GnssSetup::default()),
            reports_orientation: true,
        }
    }
}

/// A message as the host delivers it.
#[derive(Debug, Clone, Copy)]
pub enum Message {
    Imu(Imu),
    Odom(WheelOdometry),
    Gnss(Gnss),
}

impl Message {
    pub fn stamp_ns(&self) -> i64 {
        match self {
            Message::Imu(m) => m.stamp_ns,
            Message::Odom(m) => m.stamp_ns,
            Message::Gnss(m) => m.stamp_ns,
        }
    }
}

/// The true motion, every millisecond: position, heading, speed, yaw rate, acceleration.
#[derive(Debug, Clone)]
pub struct Truth {
    samples: Vec<[f64; 6]>,
}

impl Truth {
    /// (x, y, yaw) in ENU at `stamp_ns` (the nearest millisecond).
    pub fn at(&self, stamp_ns: i64) -> [f64; 3] {
        let k = ((stamp_ns + TRUTH_DT_NS / 2) / TRUTH_DT_NS) as usize;
        let s = self.samples[k.min(self.samples.len() - 1)];
        [s[0], s[1], s[2]]
    }

    pub fn end_ns(&self) -> i64 {
        (self.samples.len() as i64 - 1) * TRUTH_DT_NS
    }
}

/// A generated run: the messages in order of availability, and the truth.
#[derive(Debug, Clone)]
pub struct Run {
    pub messages: Vec<(i64, Message)>,
    pub truth: Truth,
}

/// Speed, yaw rate and acceleration at `t` seconds: 2 s speeding up, rows joined by
/// U-turns alternately left and right, 2 s slowing down.
fn control(s: &Scenario, t: f64) -> Option<(f64, f64, f64)> {
    let v = s.speed_mps;
    let ramp = 2.0;
    let row = s.row_length_m / v;
    let turn = PI * TURN_RADIUS_M / v;
    if t < ramp {
        return Some((v * t / ramp, 0.0, v / ramp));
    }
    let mut t = t - ramp;
    for i in 0..s.rows {
        if t < row {
            return Some((v, 0.0, 0.0));
        }
        t -= row;
        if i + 1 < s.rows {
            if t < turn {
                let sign = if i % 2 == 0 { 1.0 } else { -1.0 };
                return Some((v, sign * v / TURN_RADIUS_M, 0.0));
            }
            t -= turn;
        }
    }
    (t < ramp).then(|| (v * (1.0 - t / ramp), 0.0, -v / ramp))
}

fn truth(s: &Scenario) -> Truth {
    let dt = TRUTH_DT_NS as f64 * 1e-9;
    let [mut x, mut y] = START_ENU;
    let mut yaw = START_HEADING;
    let mut samples = Vec::new();
    let mut k = 0u64;
    while let Some((v, w, a)) = control(s, k as f64 * dt) {
        samples.push([x, y, yaw, v, w, a]);
        let mid = yaw + 0.5 * w * dt;
        x += v * dt * mid.cos();
        y += v * dt * mid.sin();
        yaw += w * dt;
        k += 1;
    }
    Truth { samples }
}

fn normal(rng: &mut ChaCha8Rng) -> f64 {
    StandardNormal.sample(rng)
}

/// `base_from_imu`: 0.6 m up, turned 90° about z (so the plugin must rotate its readings).
pub fn base_from_imu() -> Isometry3<f64> {
    Isometry3::from_parts(
        Translation3::new(0.1, 0.0, 0.6),
        UnitQuaternion::from_euler_angles(0.0, 0.0, FRAC_PI_2),
    )
}

/// Generates the run's messages.
pub fn generate(s: &Scenario) -> Run {
    let truth = truth(s);
    let end = truth.end_ns();
    let mut rng = ChaCha8Rng::seed_from_u64(s.seed);
    let mut messages = Vec::new();

    // Wheel odometry, 50 Hz: scale errors, a slowly wandering slip, white yaw-rate noise.
    let (mut slip, mut ox, mut oy, mut oyaw) = (0.0, 0.0, 0.0, 0.0);
    let decay = (-(ODOM_PERIOD_NS as f64 * 1e-9) / 1.0f64).exp();
    let yaw_sigma = YAW_RATE_NOISE_DENSITY * 50f64.sqrt();
    let mut t = 0;
    while t <= end {
        let sample = truth.samples[(t / TRUTH_DT_NS) as usize];
        let (v, w) = (sample[3], sample[4]);
        slip = decay * slip + (1.0 - decay * decay).sqrt() * SLIP_SIGMA * normal(&mut rng);
        let linear = v * (1.0 + SCALE_ERROR) * (1.0 - slip);
        let angular = w * (1.0 + YAW_SCALE_ERROR) + yaw_sigma * normal(&mut rng);
        if t > 0 {
            let h = ODOM_PERIOD_NS as f64 * 1e-9;
            let mid = oyaw + 0.5 * angular * h;
            ox += linear * h * mid.cos();
            oy += linear * h * mid.sin();
            oyaw += angular * h;
        }
        let pose = Isometry3::from_parts(
            Translation3::new(ox, oy, 0.0),
            UnitQuaternion::from_euler_angles(0.0, 0.0, oyaw),
        );
        messages.push((
            t,
            Message::Odom(WheelOdometry {
                stamp_ns: t,
                linear_mps: linear,
                angular_rps: angular,
                odom_from_base: Pose::new(t, &pose),
            }),
        ));
        t += ODOM_PERIOD_NS;
    }

    // IMU, 200 Hz, mounted turned: gyro with a constant bias and white noise, specific
    // force, and (if it reports one) its true orientation.
    let base_r_imu = base_from_imu().rotation;
    let gyro_sigma = GYRO_NOISE_DENSITY * 200f64.sqrt();
    let accel_sigma = ACCEL_NOISE_DENSITY * 200f64.sqrt();
    let bias = Vector3::from_fn(|_, _| GYRO_BIAS * normal(&mut rng));
    let mut t = 0;
    while t <= end {
        let sample = truth.samples[(t / TRUTH_DT_NS) as usize];
        let (yaw, v, w, a) = (sample[2], sample[3], sample[4], sample[5]);
        let gyro = base_r_imu.inverse() * Vector3::new(0.0, 0.0, w)
            + bias
            + Vector3::from_fn(|_, _| gyro_sigma * normal(&mut rng));
        let accel = base_r_imu.inverse() * Vector3::new(a, v * w, GRAVITY)
            + Vector3::from_fn(|_, _| accel_sigma * normal(&mut rng));
        let orientation = if s.reports_orientation {
            let q = (UnitQuaternion::from_euler_angles(0.0, 0.0, yaw) * base_r_imu).coords;
            [q.x, q.y, q.z, q.w]
        } else {
            [0.0; 4]
        };
        messages.push((
            t,
            Message::Imu(Imu {
                stamp_ns: t,
                accel_mps2: [accel.x, accel.y, accel.z],
                gyro_rps: [gyro.x, gyro.y, gyro.z],
                orientation_xyzw: orientation,
            }),
        ));
        t += IMU_PERIOD_NS;
    }

    // GNSS: the antenna's position with white noise, after its latency.
    if let Some(g) = s.gnss {
        let lever = Vector3::from(LEVER_ARM);
        let mut t = g.period_ns;
        while t + g.latency_ns <= end {
            let [x, y, yaw] = truth.at(t);
            let antenna = Vector3::new(x, y, 0.0)
                + UnitQuaternion::from_euler_angles(0.0, 0.0, yaw) * lever
                + Vector3::new(
                    g.sigma_m * normal(&mut rng),
                    g.sigma_m * normal(&mut rng),
                    2.0 * g.sigma_m * normal(&mut rng),
                );
            messages.push((t + g.latency_ns, Message::Gnss(fix(t, &antenna, g.sigma_m))));
            t += g.period_ns;
        }
    }
    messages.sort_by_key(|(available, _)| *available);
    Run { messages, truth }
}

/// A fixed RTK fix at `antenna` with standard deviation `sigma_m` (twice it vertically).
pub fn fix(stamp_ns: i64, antenna: &Vector3<f64>, sigma_m: f64) -> Gnss {
    let v = sigma_m * sigma_m;
    Gnss {
        stamp_ns,
        status: GnssStatus::Fixed,
        satellites: 14,
        position_enu_m: [antenna.x, antenna.y, antenna.z],
        covariance_enu_m2: [v, 0.0, 0.0, 0.0, v, 0.0, 0.0, 0.0, 4.0 * v],
        latitude_deg: 53.27,
        longitude_deg: -0.52,
        altitude_m: 40.0,
        hdop: 0.8,
    }
}

fn spec(name: &str, kind: SensorKind, rate_hz: f64, mount: &Isometry3<f64>) -> SensorSpec {
    SensorSpec {
        name: name.into(),
        kind,
        rate_hz,
        base_from_sensor_xyz: [0.0; 3],
        base_from_sensor_xyzw: [0.0, 0.0, 0.0, 1.0],
        intrinsics: BTreeMap::new(),
        noise: BTreeMap::new(),
    }
    .with_mount(mount)
}

/// The rig the plugin is given: the IMU and the odometry with their datasheet figures,
/// and the receiver with its lever arm where the scenario has one.
pub fn rig(s: &Scenario) -> Rig {
    let mut imu = spec("imu", SensorKind::Imu, 200.0, &base_from_imu());
    imu.intrinsics.insert(
        "reports_orientation".into(),
        f64::from(u8::from(s.reports_orientation)),
    );
    imu.noise = BTreeMap::from([
        ("accel_noise_density".into(), ACCEL_NOISE_DENSITY),
        ("accel_bias_random_walk".into(), 3.0e-4),
        ("gyro_noise_density".into(), GYRO_NOISE_DENSITY),
        ("gyro_bias_random_walk".into(), 2.0e-5),
    ]);
    let mut odom = spec(
        "odom",
        SensorKind::WheelOdometry,
        50.0,
        &Isometry3::identity(),
    );
    odom.noise = BTreeMap::from([
        ("scale_error".into(), SCALE_ERROR),
        ("slip_sigma".into(), SLIP_SIGMA),
        ("yaw_rate_noise_density".into(), YAW_RATE_NOISE_DENSITY),
    ]);
    let mut sensors = vec![imu, odom];
    if s.gnss.is_some() {
        let lever = Isometry3::from_parts(
            Translation3::from(Vector3::from(LEVER_ARM)),
            UnitQuaternion::identity(),
        );
        sensors.push(spec("gnss", SensorKind::Gnss, 5.0, &lever));
    }
    Rig { sensors }
}

/// Runs the plugin on `messages`: the poses it returned online, and its output.
pub fn run(config: &str, rig: &Rig, messages: &[(i64, Message)]) -> (Vec<Pose>, SlamOutput) {
    let mut system = EkfLocalization::new(config, rig).expect("the configuration is valid");
    let mut online = Vec::new();
    for (_, m) in messages {
        let pose = match m {
            Message::Imu(imu) => system.on_imu(imu),
            Message::Odom(odom) => system.on_wheel_odometry(odom),
            Message::Gnss(gnss) => system.on_gnss(gnss),
        }
        .expect("no message is an error");
        online.extend(pose);
    }
    let output = system.finish().expect("finishes");
    (online, output)
}

/// Dead reckoning: the wheel odometry's own integrated poses.
pub fn dead_reckoning(messages: &[(i64, Message)]) -> Vec<Pose> {
    messages
        .iter()
        .filter_map(|(_, m)| match m {
            Message::Odom(o) => Some(o.odom_from_base),
            _ => None,
        })
        .collect()
}

/// A stamp, the estimated position and the true one.
type Pair = (i64, [f64; 2], [f64; 2]);

/// Horizontal position errors of `poses` against the truth after the best rigid alignment
/// in the plane (evo's SE(2) alignment), for poses stamped in `[from_ns, to_ns]`.
pub fn aligned_errors(poses: &[Pose], truth: &Truth, from_ns: i64, to_ns: i64) -> Vec<(i64, f64)> {
    let pairs: Vec<Pair> = poses
        .iter()
        .map(|p| {
            let [x, y, _] = truth.at(p.stamp_ns);
            (p.stamp_ns, [p.translation[0], p.translation[1]], [x, y])
        })
        .collect();
    let n = pairs.len() as f64;
    let mean = |f: fn(&Pair) -> [f64; 2]| {
        let s = pairs
            .iter()
            .map(f)
            .fold([0.0, 0.0], |a, b| [a[0] + b[0], a[1] + b[1]]);
        [s[0] / n, s[1] / n]
    };
    let (me, mt) = (mean(|p| p.1), mean(|p| p.2));
    let (mut dot, mut cross) = (0.0, 0.0);
    for (_, e, t) in &pairs {
        let (ex, ey, tx, ty) = (e[0] - me[0], e[1] - me[1], t[0] - mt[0], t[1] - mt[1]);
        dot += ex * tx + ey * ty;
        cross += ex * ty - ey * tx;
    }
    let (s, c) = cross.atan2(dot).sin_cos();
    pairs
        .iter()
        .filter(|(t, _, _)| (from_ns..=to_ns).contains(t))
        .map(|(t, e, r)| {
            let (ex, ey) = (e[0] - me[0], e[1] - me[1]);
            let ax = c * ex - s * ey + mt[0];
            let ay = s * ex + c * ey + mt[1];
            (*t, (ax - r[0]).hypot(ay - r[1]))
        })
        .collect()
}

pub fn rms(errors: &[(i64, f64)]) -> f64 {
    (errors.iter().map(|(_, e)| e * e).sum::<f64>() / errors.len() as f64).sqrt()
}
