//! End-to-end checks of the simulator: routes, IMU, wheel odometry, lidar geometry,
//! motion distortion, determinism. One integration binary (parry's layout); each test says
//! what it guards against.

use nalgebra::{Isometry3, Point3, UnitQuaternion, Vector3};
use sim::config::{NoiseProfile, RouteSpec, SimConfig, TerrainConfig};
use sim::raycast::ParryCaster;
use sim::robot::GRAVITY;
use sim::sensors::{ImuSample, LidarScan, Message, WheelOdometry};
use sim::world::World;
use sim::{SensorSet, Simulation};

fn only(sensors: &str) -> SensorSet {
    sensors.parse().expect("valid sensor list")
}

fn noise_free(mut cfg: SimConfig) -> SimConfig {
    cfg.sensors.imu.noise = NoiseProfile::None;
    cfg.sensors.wheel_odometry.noise = NoiseProfile::None;
    cfg.sensors.lidar.noise = NoiseProfile::None;
    cfg.sensors.scan2d_front.noise = NoiseProfile::None;
    cfg.sensors.scan2d_back.noise = NoiseProfile::None;
    cfg
}

fn flat(mut cfg: SimConfig) -> SimConfig {
    cfg.terrain = TerrainConfig::flat();
    cfg
}

fn path_length(sim: &Simulation) -> f64 {
    let step = 10_000_000;
    (step..=sim.duration_ns())
        .step_by(step as usize)
        .map(|t| {
            (sim.trajectory.pose(t).translation.vector
                - sim.trajectory.pose(t - step).translation.vector)
                .norm()
        })
        .sum()
}

/// The paper's routes must keep their published lengths (±2 %) in the default world, as
/// driven by the controller on uneven ground, not just as drawn; s4 (ours) its nominal
/// 84.2 m (driven: 84.3 m).
#[test]
fn driven_routes_match_the_papers_lengths() {
    let cfg = SimConfig::default();
    let world = World::build(&cfg.vineyard, &cfg.terrain, cfg.world_seed);
    for (name, paper) in [
        ("s0", 25.0),
        ("s1", 48.6),
        ("s2", 54.6),
        ("s3", 101.2),
        ("s4", 84.2),
    ] {
        let sim = Simulation::with_world(&cfg, world.clone(), name, 0).expect("scenario builds");
        let driven = path_length(&sim);
        eprintln!("{name}: driven {driven:.2} m");
        assert!(
            (driven - paper).abs() / paper <= 0.02,
            "{name}: driven {driven:.2} m, paper {paper} m (must be within 2 %)"
        );
    }
}

/// s4 exists for true revisits: in ground truth the robot drives lane 3 eastwards along the
/// whole row twice, in two separate passes with lane 4 westwards between them, and at
/// every metre along the row the two passes are within 0.2 m and 5° of each other.
#[test]
fn s4_drives_lane_3_twice_in_the_same_direction() {
    let cfg = SimConfig::default();
    let sim = Simulation::new(&cfg, "s4", 0).expect("s4 builds");
    let v = &cfg.vineyard;
    let step = 50_000_000;
    // (t, x, y, yaw) every 0.05 s.
    type Sample = (i64, f64, f64, f64);
    let samples: Vec<Sample> = (0..=sim.duration_ns() / step)
        .map(|k| {
            let p = sim.trajectory.pose(k * step);
            let t = p.translation.vector;
            (k * step, t.x, t.y, p.rotation.euler_angles().2)
        })
        .collect();
    let in_row = |x: f64| (0.0..=v.row_length_m).contains(&x);
    // Which lane and way each in-row sample drives: (lane, eastwards).
    let lane_of = |&(_, x, y, yaw): &Sample| -> Option<(usize, bool)> {
        let lane = (0..v.lanes()).find(|&l| (y - v.lane_y(l)).abs() < 0.3)?;
        let east = yaw.cos();
        (in_row(x) && east.abs() > 20f64.to_radians().cos()).then_some((lane, east > 0.0))
    };
    // The in-row passes in order, each with its samples.
    let mut passes: Vec<((usize, bool), Vec<Sample>)> = Vec::new();
    let mut previous = None;
    for s in &samples {
        let here = lane_of(s);
        match (here, passes.last_mut()) {
            (Some(h), Some((last, points))) if Some(h) == previous && *last == h => points.push(*s),
            (Some(h), _) => passes.push((h, vec![*s])),
            (None, _) => {}
        }
        previous = here;
    }
    let order: Vec<(usize, bool)> = passes.iter().map(|(h, _)| *h).collect();
    assert_eq!(
        order,
        [(3, true), (4, false), (3, true)],
        "s4's passes through the rows (lane, eastwards)"
    );
    for (h, points) in &passes {
        let (lo, hi) = points
            .iter()
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), p| {
                (lo.min(p.1), hi.max(p.1))
            });
        assert!(
            lo < 0.1 && hi > v.row_length_m - 0.1,
            "{h:?} covers the whole row: x {lo:.2}..{hi:.2}"
        );
    }
    let (first, second) = (&passes[0].1, &passes[2].1);
    assert!(
        second[0].0 - first.last().expect("samples").0 > 30_000_000_000,
        "the passes are separate, lane 4 between them"
    );
    let nearest = |pass: &[Sample], x: f64| {
        *pass
            .iter()
            .min_by(|a, b| (a.1 - x).abs().total_cmp(&(b.1 - x).abs()))
            .expect("samples")
    };
    let mut worst = (0.0f64, 0.0f64);
    for x in (1..v.row_length_m as i32).map(f64::from) {
        let (a, b) = (nearest(first, x), nearest(second, x));
        let apart = (a.1 - b.1).hypot(a.2 - b.2);
        let turned = (a.3 - b.3).abs().to_degrees();
        worst = (worst.0.max(apart), worst.1.max(turned));
    }
    eprintln!(
        "s4: lane 3 passes at most {:.3} m and {:.2} deg apart",
        worst.0, worst.1
    );
    assert!(
        worst.0 < 0.2 && worst.1 < 5.0,
        "the two passes of lane 3 are at most {:.3} m and {:.2} deg apart",
        worst.0,
        worst.1
    );
}

/// The ground truth must respect the robot's limits: the controller filters commands, and
/// the spline must not add overshoot.
#[test]
fn ground_truth_respects_speed_and_yaw_rate_limits() {
    let cfg = SimConfig::default();
    let sim = Simulation::new(&cfg, "s2", 0).expect("s2 builds");
    let (mut v_max, mut w_max) = (0.0f64, 0.0f64);
    for t in (0..sim.duration_ns()).step_by(5_000_000) {
        let s = sim.trajectory.state(t);
        v_max = v_max.max(s.velocity.xy().norm());
        w_max = w_max.max(s.omega_in_base.z.abs());
    }
    assert!(
        v_max <= 0.5 * 1.03 && v_max > 0.45,
        "peak speed {v_max} m/s: expected about 0.5 and not above"
    );
    assert!(
        w_max <= 0.5 * 1.1,
        "peak yaw rate {w_max} rad/s exceeds 0.5 rad/s"
    );
}

/// Noise-free IMU readings are the exact derivatives of the ground truth: strapdown
/// integration along S1 (uneven terrain, a turn on the spot) must end within 1 % of the
/// distance travelled.
#[test]
fn noise_free_imu_integrates_to_ground_truth_along_s1() {
    let cfg = noise_free(SimConfig::default());
    let sim = Simulation::new(&cfg, "s1", 0).expect("s1 builds");
    let base_from_imu = cfg.sensors.imu.mount.base_from_sensor();
    let imu: Vec<ImuSample> = sim
        .stream(only("imu"))
        .filter_map(|m| match m {
            Message::Imu(s) => Some(s),
            _ => None,
        })
        .collect();
    let world_from_imu = |t| sim.trajectory.pose(t) * base_from_imu;
    let start = world_from_imu(0);
    let (mut q, mut p) = (start.rotation, start.translation.vector);
    let mut v = Vector3::zeros(); // the robot stands still at the start
    let g = Vector3::new(0.0, 0.0, -GRAVITY);
    for pair in imu.windows(2) {
        let dt = (pair[1].stamp_ns - pair[0].stamp_ns) as f64 * 1e-9;
        let a0 = q * pair[0].accel_mps2 + g;
        let omega = 0.5 * (pair[0].gyro_rps + pair[1].gyro_rps);
        let q1 = q * UnitQuaternion::from_scaled_axis(omega * dt);
        let a1 = q1 * pair[1].accel_mps2 + g;
        let v1 = v + 0.5 * (a0 + a1) * dt;
        p += 0.5 * (v + v1) * dt;
        v = v1;
        q = q1;
    }
    let end = world_from_imu(imu.last().expect("imu samples").stamp_ns);
    let error = (p - end.translation.vector).norm();
    let distance = path_length(&sim);
    assert!(
        error < 0.01 * distance,
        "integrated IMU ends {error:.3} m from ground truth after {distance:.1} m (limit 1 %)"
    );
    let yaw_error = (q.inverse() * end.rotation).angle();
    assert!(
        yaw_error < 0.01,
        "attitude error {yaw_error} rad after integration"
    );
}

/// On flat ground, noise-free wheel odometry is dead reckoning from exact rates: it must
/// follow the ground truth's motion from the start pose.
#[test]
fn noise_free_wheel_odometry_on_flat_ground_reproduces_ground_truth() {
    let cfg = flat(noise_free(SimConfig::default()));
    let sim = Simulation::new(&cfg, "s2", 0).expect("s2 builds");
    let start = sim.trajectory.pose(0);
    let odom: Vec<WheelOdometry> = sim
        .stream(only("odom"))
        .filter_map(|m| match m {
            Message::WheelOdometry(o) => Some(o),
            _ => None,
        })
        .collect();
    assert!(
        odom.len() > 50 * 100,
        "50 Hz over more than 100 s, got {}",
        odom.len()
    );
    let mut worst = 0.0f64;
    for o in &odom {
        let truth = start.inverse() * sim.trajectory.pose(o.stamp_ns);
        let d = (truth.translation.vector - o.odom_from_base.translation.vector).norm();
        worst = worst.max(d);
        let dyaw = (truth.rotation.inverse() * o.odom_from_base.rotation).angle();
        assert!(
            dyaw < 1e-3,
            "odometry yaw off by {dyaw} rad at {} ns",
            o.stamp_ns
        );
    }
    assert!(
        worst < 0.01,
        "odometry drifts {worst:.4} m from ground truth on flat ground without noise"
    );
}

/// With noise on uneven ground the odometry must drift (else the baseline is meaningless),
/// but stay a plausible odometry (a few percent of distance).
#[test]
fn noisy_wheel_odometry_drifts_plausibly() {
    let cfg = SimConfig::default();
    let sim = Simulation::new(&cfg, "s1", 3).expect("s1 builds");
    let start = sim.trajectory.pose(0);
    let last = sim
        .stream(only("odom"))
        .filter_map(|m| match m {
            Message::WheelOdometry(o) => Some(o),
            _ => None,
        })
        .last()
        .expect("odometry messages");
    let truth = start.inverse() * sim.trajectory.pose(last.stamp_ns);
    let drift = (truth.translation.vector - last.odom_from_base.translation.vector).norm();
    assert!(
        (0.02..5.0).contains(&drift),
        "odometry end drift {drift:.3} m over 48.6 m: expected between 2 cm and 5 m"
    );
}

/// Ray geometry: on flat ground away from the vines, each downward beam of a resting
/// VLP-16 at 1.56 m must hit the ground at 1.56 / sin(-elevation).
#[test]
fn lidar_points_on_flat_ground_fall_at_expected_ranges() {
    let mut cfg = flat(noise_free(SimConfig::default()));
    cfg.scenarios.insert(
        "field".into(),
        RouteSpec::Waypoints {
            points: vec![[-20.0, 12.0], [-19.0, 12.0]],
        },
    );
    let sim = Simulation::new(&cfg, "field", 0).expect("field route builds");
    let scan = first_scan(&sim);
    let lidar = &cfg.sensors.lidar;
    let mut checked = 0;
    for p in scan.points.iter().filter(|p| p.ring <= 4) {
        let elevation = lidar.min_elevation_deg + f64::from(p.ring) * 2.0;
        let expected = 1.56 / (-elevation.to_radians()).sin();
        let range = f64::from(Vector3::new(p.x, p.y, p.z).norm());
        assert!(
            (range - expected).abs() < 2e-3,
            "ring {} range {range:.4} m, expected {expected:.4} m on flat ground",
            p.ring
        );
        checked += 1;
    }
    assert_eq!(
        checked,
        5 * 1800,
        "every beam of rings 0-4 returns from the ground"
    );

    // With noise, the range errors have the datasheet's σ.
    let mut noisy_cfg = cfg.clone();
    noisy_cfg.sensors.lidar.noise = NoiseProfile::Typical;
    let noisy = Simulation::new(&noisy_cfg, "field", 5).expect("builds");
    let scan = first_scan(&noisy);
    let errors: Vec<f64> = scan
        .points
        .iter()
        .filter(|p| p.ring <= 4)
        .map(|p| {
            let expected =
                1.56 / (-(lidar.min_elevation_deg + f64::from(p.ring) * 2.0).to_radians()).sin();
            f64::from(Vector3::new(p.x, p.y, p.z).norm()) - expected
        })
        .collect();
    let sigma = (errors.iter().map(|e| e * e).sum::<f64>() / errors.len() as f64).sqrt();
    assert!(
        (0.007..0.009).contains(&sigma),
        "range noise σ {sigma:.5} m, datasheet 0.008 m"
    );
}

fn first_scan(sim: &Simulation) -> LidarScan {
    sim.stream(only("lidar"))
        .find_map(|m| match m {
            Message::Lidar(s) => Some(s),
            _ => None,
        })
        .expect("a lidar scan")
}

/// Each column fires from the pose at its own time: a scan taken while turning on the spot
/// is distorted when every point is placed with the scan's stamp pose, and placing each
/// point with the ground-truth pose at its own time puts it back on the scene's surfaces.
#[test]
fn turning_scan_is_distorted_and_ground_truth_deskewing_removes_it() {
    let cfg = noise_free(SimConfig::default());
    let sim = Simulation::new(&cfg, "s1", 0).expect("s1 builds");
    let base_from_lidar = cfg.sensors.lidar.mount.base_from_sensor();
    // The scan during which the robot turns fastest (the turn at the end of the lane).
    let scan = sim
        .stream(only("lidar"))
        .filter_map(|m| match m {
            Message::Lidar(s) => Some(s),
            _ => None,
        })
        .max_by(|a, b| {
            let w = |s: &LidarScan| {
                sim.trajectory
                    .state(s.stamp_ns + s.sweep_ns / 2)
                    .omega_in_base
                    .z
                    .abs()
            };
            w(a).total_cmp(&w(b))
        })
        .expect("scans");
    let w = sim
        .trajectory
        .state(scan.stamp_ns + scan.sweep_ns / 2)
        .omega_in_base
        .z
        .abs();
    assert!(w > 0.3, "the chosen scan turns at {w} rad/s");
    let surfaces = ParryCaster::build(&sim.world.mesh);
    let place = |pose: Isometry3<f64>, p: &sim::sensors::LidarPoint| -> Point3<f32> {
        (pose * base_from_lidar * Point3::new(f64::from(p.x), f64::from(p.y), f64::from(p.z)))
            .cast()
    };
    let (mut naive, mut deskewed) = (Vec::new(), Vec::new());
    for p in scan.points.iter().step_by(7) {
        let stamp_pose = sim.trajectory.pose(scan.stamp_ns);
        let own_pose = sim
            .trajectory
            .pose(scan.stamp_ns + (f64::from(p.time_s) * 1e9).round() as i64);
        naive.push(surfaces.distance_to_surface(&place(stamp_pose, p)));
        deskewed.push(surfaces.distance_to_surface(&place(own_pose, p)));
    }
    let mean = |v: &[f32]| v.iter().sum::<f32>() / v.len() as f32;
    let (naive, deskewed) = (mean(&naive), mean(&deskewed));
    // Ground points stay on the (nearly flat) ground when turned about the vertical, so the
    // mean understates the distortion of vertical structures; it is still tens of times the
    // deskewed residual, which is float rounding.
    assert!(
        naive > 0.02 && naive > 20.0 * deskewed,
        "a scan turning at {w:.2} rad/s should be distorted: mean distance to surface {naive:.4} m stamped, {deskewed:.5} m deskewed"
    );
    assert!(
        deskewed < 0.002,
        "deskewed points should lie on surfaces: mean distance {deskewed:.5} m"
    );
}

fn digest(sim: &Simulation, sensors: SensorSet, until_ns: i64) -> (u64, usize) {
    let mut h: u64 = 0xcbf2_9ce4_8422_2325;
    let mut n = 0;
    for m in sim.stream(sensors).take_while(|m| m.stamp_ns() < until_ns) {
        // Debug formatting of floats is exact (shortest round-trip), so equal text means equal bits.
        for b in format!("{m:?}").bytes() {
            h = (h ^ u64::from(b)).wrapping_mul(0x0000_0100_0000_01b3);
        }
        n += 1;
    }
    (h, n)
}

/// Determinism: the same configuration and seed give identical streams, on any number of
/// threads; another seed changes the noise.
#[test]
fn same_seed_gives_identical_stream_and_another_seed_a_different_one() {
    let cfg = SimConfig::default();
    let until = 3_000_000_000;
    let a = digest(
        &Simulation::new(&cfg, "s0", 11).expect("builds"),
        SensorSet::ALL,
        until,
    );
    let b = digest(
        &Simulation::new(&cfg, "s0", 11).expect("builds"),
        SensorSet::ALL,
        until,
    );
    let c = digest(
        &Simulation::new(&cfg, "s0", 12).expect("builds"),
        SensorSet::ALL,
        until,
    );
    assert!(
        a.1 > 1000,
        "3 s of all sensors is more than a thousand messages, got {}",
        a.1
    );
    assert_eq!(a, b, "same seed must give the identical stream");
    // Whatever the number of threads: the lidar, the 2D scans and the camera all split
    // their work over rayon's threads.
    let short = 1_000_000_000;
    let a1 = digest(
        &Simulation::new(&cfg, "s0", 11).expect("builds"),
        SensorSet::ALL,
        short,
    );
    for threads in [1, 3] {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .expect("thread pool");
        let t = pool.install(|| {
            digest(
                &Simulation::new(&cfg, "s0", 11).expect("builds"),
                SensorSet::ALL,
                short,
            )
        });
        assert_eq!(a1, t, "{threads} thread(s) must give the identical stream");
    }
    assert_eq!(a.1, c.1, "another seed gives the same number of messages");
    assert_ne!(a.0, c.0, "another seed must give different noise");
}

/// The stream is ordered by availability time, each sensor at its rate.
#[test]
fn stream_is_time_ordered_with_the_configured_rates() {
    let cfg = SimConfig::default();
    let sim = Simulation::new(&cfg, "s0", 0).expect("builds");
    let mut last_ready = i64::MIN;
    let mut counts = std::collections::BTreeMap::new();
    for m in sim
        .stream(SensorSet::ALL)
        .take_while(|m| m.stamp_ns() < 2_000_000_000)
    {
        let ready = match &m {
            Message::Lidar(s) => s.stamp_ns + s.sweep_ns,
            Message::Scan2d(s) => {
                s.stamp_ns
                    + (s.time_increment_s as f64 * 1e9 * (s.ranges_m.len() - 1) as f64).round()
                        as i64
            }
            other => other.stamp_ns(),
        };
        assert!(
            ready >= last_ready,
            "{} at {ready} ns came after a message ready at {last_ready}",
            m.sensor()
        );
        last_ready = ready;
        *counts.entry(m.sensor()).or_insert(0) += 1;
    }
    // Messages stamped in [0, 2 s): rates 100, 200, 50, 40, 40, 10 Hz.
    for (sensor, expected) in [
        ("gt", 200),
        ("imu", 400),
        ("odom", 100),
        ("scan_front", 80),
        ("scan_back", 80),
        ("lidar", 20),
    ] {
        let got = counts.get(sensor).copied().unwrap_or(0);
        assert!(
            (expected - 1..=expected).contains(&got),
            "{sensor}: {got} messages in 2 s, expected {expected}"
        );
    }
}

/// A world with an RTK receiver streams its epochs at the configured rate, each delivered
/// its latency after its stamp and in order of delivery among the other sensors; a fix
/// lies within five of its reported σ of the antenna's true position (the mast over the
/// base); a world without a receiver streams none; the same seed gives the same fixes.
#[test]
fn a_gnss_receiver_streams_its_fixes_late_by_its_latency() {
    let mut cfg = SimConfig::default();
    cfg.sensors.gnss.profile = sim::config::GnssProfile::Rtk;
    cfg.validate().expect("valid");
    let sim = Simulation::new(&cfg, "s0", 3).expect("builds");
    let fixes = |sim: &Simulation| -> Vec<sim::sensors::gnss::GnssFix> {
        let mut last_ready = i64::MIN;
        sim.stream(only("gt,imu,gnss"))
            .take_while(|m| m.stamp_ns() < 20_000_000_000)
            .filter_map(|m| {
                let ready = match &m {
                    Message::Gnss(g) => g.stamp_ns + g.latency_ns,
                    other => other.stamp_ns(),
                };
                assert!(ready >= last_ready, "{} out of order", m.sensor());
                last_ready = ready;
                match m {
                    Message::Gnss(g) => Some(g),
                    _ => None,
                }
            })
            .collect()
    };
    let got = fixes(&sim);
    assert!(
        (99..=101).contains(&got.len()),
        "{} epochs in 20 s at 5 Hz",
        got.len()
    );
    assert_eq!(got[1].stamp_ns - got[0].stamp_ns, 200_000_000);
    assert!(got.iter().all(|g| g.latency_ns == 50_000_000));
    let mut with_fix = 0;
    for g in &got {
        let Some(p) = g.position_enu_m else { continue };
        with_fix += 1;
        let truth = (sim.trajectory.pose(g.stamp_ns) * Isometry3::translation(0.0, 0.0, 1.7))
            .translation
            .vector;
        let d = p - truth;
        let (sh, sv) = (g.variance_enu_m2[0].sqrt(), g.variance_enu_m2[2].sqrt());
        assert!(
            d.x.abs() < 5.0 * sh && d.y.abs() < 5.0 * sh && d.z.abs() < 5.0 * sv,
            "{:?} off by {d} with sigma {sh}, {sv}",
            g.status
        );
        let [lat, lon, _] = g.geodetic.expect("a fix has its WGS-84 position");
        assert!((lat - 53.2686).abs() < 0.01 && (lon + 0.5245).abs() < 0.01);
    }
    assert!(with_fix > 0, "no fix in 20 s");
    assert_eq!(fixes(&Simulation::new(&cfg, "s0", 3).expect("builds")), got);
    let none = Simulation::new(&SimConfig::default(), "s0", 3).expect("builds");
    assert!(fixes(&none).is_empty());
}

/// Reflections act through the world's mesh. Along s1 in full canopy with the antenna at
/// 0.8 m the rows reflect: the stream changes; where both are fixed a fix moves by carrier
/// multipath alone, millimetres (each satellite's at most `asin(α)·λ/2π`, 5 mm), NLOS
/// satellites left out of it. Under an open sky they change nothing.
#[test]
fn gnss_reflections_act_below_the_canopy_and_never_under_an_open_sky() {
    use sim::sensors::gnss::{FixStatus, GnssFix};
    let stream = |reflections: bool, open_sky: bool| -> Vec<GnssFix> {
        let mut cfg = SimConfig::default();
        cfg.vineyard.growth_stage = 4.0;
        cfg.sensors.gnss.profile = sim::config::GnssProfile::Rtk;
        cfg.sensors.gnss.mount_xyz_m = [0.0, 0.0, 0.8];
        cfg.sensors.gnss.reflections = reflections;
        cfg.sensors.gnss.open_sky = open_sky;
        cfg.validate().expect("valid");
        let sim = Simulation::new(&cfg, "s1", 3).expect("builds");
        sim.stream(only("gnss"))
            .filter_map(|m| match m {
                Message::Gnss(g) => Some(g),
                _ => None,
            })
            .collect()
    };
    let (on, off) = (stream(true, false), stream(false, false));
    assert_eq!(on.len(), off.len());
    assert_ne!(on, off, "the rows reflect");
    let mut moved = 0;
    for (a, b) in on.iter().zip(&off) {
        if a.status == FixStatus::Fixed && b.status == FixStatus::Fixed {
            let d = (a.position_enu_m.expect("fix") - b.position_enu_m.expect("fix")).norm();
            assert!(d < 0.05, "{}: a fix moved {d} m", a.stamp_ns);
            moved += usize::from(d > 0.0);
        }
    }
    assert!(moved > 0, "no fix carries multipath");
    assert_eq!(stream(true, true), stream(false, true), "open sky");
}

/// The reported orientation's error is the configured Gauss–Markov process: zero error
/// unless asked, and with a short correlation time an RMS about its σ per axis (yaw
/// measured about the vertical, against the true orientation), the same for the same seed.
#[test]
fn the_imu_orientation_carries_its_configured_error() {
    let mut cfg = SimConfig::default();
    cfg.sensors.imu.reports_orientation = true;
    let errors = |cfg: &SimConfig| -> Vec<(f64, f64)> {
        let sim = Simulation::new(cfg, "s0", 5).expect("builds");
        let base_r_imu = cfg.sensors.imu.mount.base_from_sensor().rotation;
        sim.stream(only("imu"))
            .take_while(|m| m.stamp_ns() < 10_000_000_000)
            .filter_map(|m| match m {
                Message::Imu(ImuSample {
                    stamp_ns,
                    orientation: Some(q),
                    ..
                }) => {
                    let truth = sim.trajectory.pose(stamp_ns).rotation * base_r_imu;
                    let (roll, pitch, yaw) = (q * truth.inverse()).euler_angles();
                    Some((roll.hypot(pitch), yaw))
                }
                _ => None,
            })
            .collect()
    };
    assert!(
        errors(&cfg)
            .iter()
            .all(|&(rp, y)| rp < 1e-9 && y.abs() < 1e-9)
    );
    cfg.sensors.imu.orientation_roll_pitch_sigma_rad = 0.01;
    cfg.sensors.imu.orientation_yaw_sigma_rad = 0.02;
    cfg.sensors.imu.orientation_tau_s = 0.1;
    let noisy = errors(&cfg);
    // 2000 samples over 100 correlation times.
    let rms = |f: &dyn Fn(&(f64, f64)) -> f64| {
        (noisy.iter().map(|e| f(e).powi(2)).sum::<f64>() / noisy.len() as f64).sqrt()
    };
    let yaw = rms(&|e| e.1);
    // Roll and pitch together: √2 σ.
    let tilt = rms(&|e| e.0);
    assert!((0.015..0.026).contains(&yaw), "yaw error RMS {yaw}");
    assert!((0.010..0.0185).contains(&tilt), "tilt error RMS {tilt}");
    assert_eq!(errors(&cfg), noisy);
}

/// At rest the accelerometer reads gravity up and the gyro zero.
#[test]
fn resting_imu_reads_gravity() {
    let cfg = flat(noise_free(SimConfig::default()));
    let sim = Simulation::new(&cfg, "s0", 0).expect("builds");
    let Some(Message::Imu(first)) = sim.stream(only("imu")).next() else {
        panic!("first message should be an IMU sample");
    };
    assert!(
        (first.accel_mps2 - Vector3::new(0.0, 0.0, GRAVITY)).norm() < 1e-9,
        "at rest: {:?}",
        first.accel_mps2
    );
    assert!(
        first.gyro_rps.norm() < 1e-12,
        "at rest: {:?}",
        first.gyro_rps
    );
}

/// A camera frame rendered on its own (`Simulation::rgbd_frame_at`, what an evaluation
/// shows of a loop) is byte for byte the frame the stream gave at that stamp, noise
/// included, and a stamp between frames gives the latest frame before it.
#[test]
fn a_camera_frame_rendered_alone_is_the_streams_frame() {
    let sim = Simulation::new(&SimConfig::default(), "s0", 3).expect("S0 builds");
    let frames: Vec<sim::sensors::RgbdFrame> = sim
        .stream(only("rgbd"))
        .filter_map(|m| match m {
            Message::Rgbd(f) => Some(f),
            _ => None,
        })
        .take(6)
        .collect();
    let last = &frames[5];
    let alone = sim.rgbd_frame_at(last.stamp_ns).expect("frame 5");
    assert_eq!(alone.stamp_ns, last.stamp_ns);
    assert!(
        alone.image.rgb == last.image.rgb && alone.image.depth_m == last.image.depth_m,
        "the same bytes"
    );
    let between = sim
        .rgbd_frame_at(frames[4].stamp_ns + 1)
        .expect("between frames 4 and 5");
    assert_eq!(between.stamp_ns, frames[4].stamp_ns);
    assert!(between.image.rgb == frames[4].image.rgb);
    assert!(sim.rgbd_frame_at(-1).is_none());
    assert!(sim.rgbd_frame_at(sim.duration_ns() + 1).is_none());
}

/// Sensors on late clocks (`clock_offset_ns`): the same measurements, byte for byte, each
/// stamped and delivered that much later (never before the IMU samples up to its stamp);
/// what an evaluation renders at a stamp (`rgbd_frame_at`, `lidar_sweep_at`) follows.
#[test]
fn a_late_clock_stamps_the_same_measurements_later() {
    const CAMERA_NS: i64 = 30_000_000;
    const LIDAR_NS: i64 = 7_000_000;
    let mut late = SimConfig::default();
    late.sensors.camera.clock_offset_ns = CAMERA_NS;
    late.sensors.lidar.clock_offset_ns = LIDAR_NS;
    let messages = |config: &SimConfig| -> (Simulation, Vec<Message>) {
        let sim = Simulation::new(config, "s0", 3).expect("S0 builds");
        let m = sim
            .stream(only("imu,lidar,rgbd"))
            .take_while(|m| m.stamp_ns() < 250_000_000)
            .collect();
        (sim, m)
    };
    let (_, on_time) = messages(&SimConfig::default());
    let (sim, shifted) = messages(&late);
    let of = |list: &[Message], sensor: &str| -> Vec<Message> {
        list.iter()
            .filter(|m| m.sensor() == sensor)
            .cloned()
            .collect()
    };
    let imu = of(&on_time, "imu");
    assert_eq!(of(&shifted, "imu"), imu, "the reference clock is untouched");
    for (sensor, offset) in [("rgbd", CAMERA_NS), ("lidar", LIDAR_NS)] {
        let a = of(&on_time, sensor);
        let b = of(&shifted, sensor);
        assert!(a.len() >= 2, "{sensor}: {} messages", a.len());
        for (a, b) in a.iter().zip(&b) {
            let mut a = a.clone();
            a.shift_stamp(offset);
            assert!(
                a == *b,
                "{sensor}: the same measurement, stamped {offset} ns later"
            );
        }
    }
    // Delivered no earlier than its stamp: every IMU sample stamped at or before a late
    // message came before it (a frame exactly then, a sweep, stamped at its start, at its
    // end).
    for (i, m) in shifted.iter().enumerate() {
        let before = shifted[..i].iter().filter(|p| p.sensor() == "imu").count();
        let due = imu.iter().filter(|p| p.stamp_ns() <= m.stamp_ns()).count();
        match m.sensor() {
            "rgbd" => assert_eq!(before, due, "frame stamped {}", m.stamp_ns()),
            "lidar" => assert!(before >= due, "sweep stamped {}", m.stamp_ns()),
            _ => {}
        }
    }
    let Message::Rgbd(frame) = &of(&shifted, "rgbd")[1] else {
        unreachable!()
    };
    let alone = sim.rgbd_frame_at(frame.stamp_ns).expect("frame 1");
    assert_eq!(alone.stamp_ns, frame.stamp_ns);
    assert!(
        alone.image.rgb == frame.image.rgb,
        "the same frame by its late stamp"
    );
    let first = of(&shifted, "rgbd")[0].stamp_ns();
    assert_eq!(first, CAMERA_NS, "the first frame, taken at 0");
    let before = sim.rgbd_frame_at(frame.stamp_ns - 1).expect("frame 0");
    assert_eq!(
        before.stamp_ns, first,
        "a stamp before frame 1's is frame 0's"
    );
    assert!(
        sim.rgbd_frame_at(CAMERA_NS - 1).is_none(),
        "before the first stamp"
    );
    let scan = of(&shifted, "lidar")[1].stamp_ns();
    assert_eq!(sim.lidar_sweep_at(scan).expect("sweep 1").stamp_ns, scan);
}

/// A lidar sweep cast on its own (`Simulation::lidar_sweep_at`, what an evaluation shows of
/// a lidar system's loop) is the stream's sweep at that stamp without its range noise: with
/// the noise off, point for point the same; with it on, the same beams within a few σ.
#[test]
fn a_lidar_sweep_cast_alone_is_the_streams_sweep_without_noise() {
    let sweeps = |config: &SimConfig| -> (Simulation, Vec<LidarScan>) {
        let sim = Simulation::new(config, "s0", 3).expect("S0 builds");
        let scans = sim
            .stream(only("lidar"))
            .filter_map(|m| match m {
                Message::Lidar(s) => Some(s),
                _ => None,
            })
            .take(4)
            .collect();
        (sim, scans)
    };
    let mut quiet = SimConfig::default();
    quiet.sensors.lidar.noise = NoiseProfile::None;
    let (sim, scans) = sweeps(&quiet);
    let alone = sim.lidar_sweep_at(scans[3].stamp_ns + 1).expect("sweep 3");
    assert_eq!(alone.stamp_ns, scans[3].stamp_ns);
    assert_eq!(alone.points, scans[3].points, "noise off: the same points");

    let (sim, scans) = sweeps(&SimConfig::default());
    let alone = sim.lidar_sweep_at(scans[2].stamp_ns).expect("sweep 2");
    let sigma = SimConfig::default().sensors.lidar.range_sigma_m as f32;
    let range = |p: &sim::sensors::LidarPoint| (p.x * p.x + p.y * p.y + p.z * p.z).sqrt();
    assert!(!alone.points.is_empty());
    // The noisy stream may lose or gain a point at the range limits; pair them by beam.
    let key = |p: &sim::sensors::LidarPoint| (p.ring, (p.time_s * 1e7).round() as i64);
    let noisy: std::collections::BTreeMap<_, _> =
        scans[2].points.iter().map(|p| (key(p), range(p))).collect();
    let mut paired = 0;
    for p in &alone.points {
        if let Some(r) = noisy.get(&key(p)) {
            assert!((r - range(p)).abs() < 6.0 * sigma, "{r} vs {}", range(p));
            paired += 1;
        }
    }
    assert!(
        paired * 100 >= alone.points.len() * 99,
        "{paired} of {}",
        alone.points.len()
    );
    assert!(sim.lidar_sweep_at(-1).is_none());
    assert!(sim.lidar_sweep_at(sim.duration_ns() + 1).is_none());
}

/// A pixel's surface (`Simulation::surface_at_pixel`, what an evaluation says a matched
/// keypoint lay on): a fence panel put 3 m ahead of the robot's start, across its view, is
/// what the centre pixel sees, told apart from the posts whose wood it shares; without the
/// panel the same pixel sees something else; a pixel far above the horizon sees nothing.
#[test]
fn a_pixel_sees_the_fence_panel_put_in_front_of_the_camera() {
    let plain = SimConfig::default();
    let sim = Simulation::new(&plain, "s0", 0).expect("S0 builds");
    let start = sim.trajectory.pose(0);
    let ahead = start * Point3::new(3.0, 0.0, 0.0);
    let yaw = start.rotation.euler_angles().2.to_degrees() + 90.0;
    let (cx, cy) = {
        let c = &plain.sensors.camera;
        (0.5 * (c.width as f64 - 1.0), 0.5 * (c.height as f64 - 1.0))
    };
    let without = sim.surface_at_pixel(0, cx, cy);
    assert_ne!(without, Some(sim::Surface::Fence));

    let mut fenced = plain.clone();
    fenced.fence.panels = vec![[ahead.x, ahead.y, yaw]];
    fenced.fence.panel_size_m = [4.0, 0.15, 3.0];
    let sim = Simulation::new(&fenced, "s0", 0).expect("S0 with a panel builds");
    assert_eq!(sim.surface_at_pixel(0, cx, cy), Some(sim::Surface::Fence));
    assert_eq!(
        sim.surface_at_pixel(0, cx, -100_000.0),
        None,
        "straight up: the sky"
    );
    assert_eq!(sim::Surface::Fence.name(), "fence");
}
