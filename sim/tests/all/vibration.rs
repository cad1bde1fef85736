//! `robot.vibration`: the IMU feels each band's RMS as configured, the body's pose and its
//! derivatives agree, and the wheel encoders do not feel it.

use std::f64::consts::TAU;

use sim::config::VibrationConfig;
use sim::sensors::Message;
use sim::{SensorSet, SimConfig, Simulation};

/// The study's `vibration` variant (Vulpi et al. 2021's farm logs): the values the test
/// holds the model to, read from the file a sweep runs.
fn sourced() -> VibrationConfig {
    let file: toml::Table = include_str!("../../../configs/study/realism/factors-paper-world.toml")
        .parse()
        .expect("sweep file");
    let variant = file["variants"]["vibration"].as_table().expect("variant");
    let mut table = toml::Table::new();
    for (path, value) in variant {
        let key = path
            .strip_prefix("robot.vibration.")
            .expect("a vibration key");
        table.insert(key.to_owned(), value.clone());
    }
    toml::Value::Table(table)
        .try_into()
        .expect("a vibration table")
}

fn world(vibration: Option<&VibrationConfig>) -> SimConfig {
    let mut cfg = SimConfig::from_toml_str("profile = \"ideal\"\n", "ideal").expect("world");
    if let Some(v) = vibration {
        cfg.robot.vibration = v.clone();
    }
    cfg
}

/// An IMU sample: stamp, specific force, angular rate.
type Sample = (i64, [f64; 3], [f64; 3]);

/// The IMU's samples of S0.
fn imu(cfg: &SimConfig, seed: u64) -> (Simulation, Vec<Sample>) {
    let sim = Simulation::new(cfg, "s0", seed).expect("simulation");
    let set = SensorSet {
        imu: true,
        ..SensorSet::default()
    };
    let samples = sim
        .stream(set)
        .filter_map(|m| match m {
            Message::Imu(s) => Some((s.stamp_ns, s.accel_mps2.into(), s.gyro_rps.into())),
            _ => None,
        })
        .collect();
    (sim, samples)
}

/// Mean square within `lo..hi` Hz of `x` sampled at `rate` (Hann window, one-sided
/// periodogram summed over the band's bins).
fn band_mean_square(x: &[f64], rate: f64, lo: f64, hi: f64) -> f64 {
    let n = x.len();
    let w: Vec<f64> = (0..n)
        .map(|i| 0.5 - 0.5 * (TAU * i as f64 / n as f64).cos())
        .collect();
    let mean = x.iter().sum::<f64>() / n as f64;
    let xw: Vec<f64> = x.iter().zip(&w).map(|(v, w)| (v - mean) * w).collect();
    let norm = w.iter().map(|w| w * w).sum::<f64>() * rate;
    let df = rate / n as f64;
    let (k0, k1) = ((lo / df).ceil() as usize, (hi / df).floor() as usize);
    (k0..=k1)
        .map(|k| {
            let (mut re, mut im) = (0.0, 0.0);
            let step = TAU * k as f64 / n as f64;
            for (i, v) in xw.iter().enumerate() {
                let (s, c) = (step * i as f64).sin_cos();
                re += v * c;
                im -= v * s;
            }
            2.0 * (re * re + im * im) / norm * df
        })
        .sum()
}

/// Under `ideal` (no IMU noise), the difference the vibration makes to the IMU's readings
/// on S0's straight at the reference speed has, band by band and axis by axis, the RMS the
/// model was given: mean squares averaged over eight seeds' draws within 15 % (a sum of
/// eight cosines a band fluctuates by some ±12 % over one 30 s window; sixteen seeds'
/// average came within 4 % of every band but the horizontal axes' lowest, to which the
/// tilt's gravity adds 6-10 %).
#[test]
fn the_imu_feels_each_bands_rms() {
    let v = sourced();
    let (still, base) = imu(&world(None), 0);
    let rate = still.config.sensors.imu.rate_hz;
    // The longest stretch at the reference speed: the nominal wheel speed within 1 % of it
    // on the straight (the amplitude's scale within 1.2 % of 1).
    let at_speed: Vec<bool> = base
        .iter()
        .map(|(t, ..)| {
            let s = still.trajectory.nominal_state(*t);
            (s.velocity.norm() / v.reference_speed_mps - 1.0).abs() < 0.01
                && s.omega_in_base.z.abs() < 0.01
        })
        .collect();
    let (mut first, mut len, mut run) = (0, 0, 0);
    for (i, &ok) in at_speed.iter().enumerate() {
        run = if ok { run + 1 } else { 0 };
        if run > len {
            (first, len) = (i + 1 - run, run);
        }
    }
    let n = (len as f64 / rate).floor() as usize * rate as usize;
    assert!(n as f64 / rate >= 30.0, "{} s at speed", n as f64 / rate);
    let seeds = [1, 2, 3, 4, 5, 6, 7, 8];
    let mut measured = [[[0.0; 4]; 3]; 2];
    for seed in seeds {
        let (_, shaken) = imu(&world(Some(&v)), seed);
        for (kind, table) in measured.iter_mut().enumerate() {
            for (axis, bands) in table.iter_mut().enumerate() {
                let x: Vec<f64> = (first..first + n)
                    .map(|i| {
                        let (a, b) = (&shaken[i], &base[i]);
                        assert_eq!(a.0, b.0);
                        if kind == 0 {
                            a.1[axis] - b.1[axis]
                        } else {
                            a.2[axis] - b.2[axis]
                        }
                    })
                    .collect();
                for (band, ms) in bands.iter_mut().enumerate() {
                    let (lo, hi) = (v.bands_hz[band], v.bands_hz[band + 1]);
                    *ms += band_mean_square(&x, rate, lo, hi) / seeds.len() as f64;
                }
            }
        }
    }
    for (kind, (name, want)) in [("accel", &v.accel_rms_mps2), ("rate", &v.rate_rms_rps)]
        .into_iter()
        .enumerate()
    {
        for axis in 0..3 {
            for band in 0..4 {
                let got = measured[kind][axis][band].sqrt();
                let w = want[axis][band];
                assert!(
                    (got / w - 1.0).abs() < 0.15,
                    "{name} axis {axis} band {band}: RMS {got:.4} for {w:.4}"
                );
            }
        }
    }
}

/// The vibrating body's state is its pose's derivative: central differences of the pose
/// give the state's velocity, acceleration and body rates (the vibration's translations
/// turned by the heading, its rotations on roll, pitch and yaw), wherever the robot moves
/// (the amplitude's scale held at 1 by a zero exponent: its own rate of change is what the
/// model leaves out); and the body moves off the spline by millimetres and milliradians.
#[test]
fn the_shaking_pose_and_its_state_agree() {
    let mut vibration = sourced();
    vibration.speed_exponent = 0.0;
    let sim = Simulation::new(&world(Some(&vibration)), "s1", 7).expect("simulation");
    let tr = &sim.trajectory;
    let h = 100_000; // 0.1 ms
    let hs = h as f64 * 1e-9;
    let mut moved = (0.0f64, 0.0f64);
    let mut checked = 0;
    for t in (2_000_000_000..tr.duration_ns() - 2_000_000_000).step_by(250_000_000) {
        let speed = tr.nominal_state(t).velocity.norm();
        let s = tr.state(t);
        let off = tr.nominal_pose(t).inverse() * s.world_from_base;
        moved.0 = moved.0.max(off.translation.vector.norm());
        moved.1 = moved.1.max(off.rotation.angle());
        if speed < 0.05 {
            continue;
        }
        checked += 1;
        let (a, b) = (tr.pose(t - h), tr.pose(t + h));
        let v = (b.translation.vector - a.translation.vector) / (2.0 * hs);
        assert!(
            (v - s.velocity).norm() < 1e-5,
            "velocity at {t}: {v} against {}",
            s.velocity
        );
        let (sa, sb) = (tr.state(t - h), tr.state(t + h));
        let acc = (sb.velocity - sa.velocity) / (2.0 * hs);
        assert!(
            (acc - s.acceleration).norm() < 1e-3,
            "acceleration at {t}: {acc} against {}",
            s.acceleration
        );
        let turn = (a.rotation.inverse() * b.rotation).scaled_axis() / (2.0 * hs);
        assert!(
            (turn - s.omega_in_base).norm() < 1e-4,
            "body rate at {t}: {turn} against {}",
            s.omega_in_base
        );
    }
    assert!(checked > 50, "{checked} instants checked");
    assert!(
        moved.0 > 1e-4 && moved.0 < 0.05,
        "moved off the spline by {} m",
        moved.0
    );
    assert!(
        moved.1 > 1e-4 && moved.1 < 0.05,
        "turned off it by {} rad",
        moved.1
    );
}

/// The wheel encoders count the rolling: their messages over S0 are the same with and
/// without the vibration, while the IMU's differ.
#[test]
fn the_wheels_do_not_feel_it() {
    let stream = |cfg: &SimConfig, set: SensorSet| -> Vec<String> {
        let sim = Simulation::new(cfg, "s0", 3).expect("simulation");
        sim.stream(set).map(|m| format!("{m:?}")).collect()
    };
    let odom = SensorSet {
        wheel_odometry: true,
        ..SensorSet::default()
    };
    let imu = SensorSet {
        imu: true,
        ..SensorSet::default()
    };
    let (still, shaken) = (world(None), world(Some(&sourced())));
    assert_eq!(stream(&still, odom), stream(&shaken, odom));
    assert_ne!(stream(&still, imu), stream(&shaken, imu));
}
