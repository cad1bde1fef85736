//! `mount_error`: the sensors sit off their nominal mounts by the drawn error, and the
//! draws have the configured spread.

use sim::config::{MountError, Profile};
use sim::sensors::Message;
use sim::{SensorSet, SimConfig, Simulation};

/// Over many runs' seeds the drawn offsets and rotations are zero-mean with the configured
/// σ on every axis (400 draws: the sample σ lies within ±10 % of σ with probability > 99 %).
#[test]
fn drawn_errors_have_the_configured_spread() {
    let error = MountError {
        sigma_m: 0.02,
        sigma_deg: 1.0,
    };
    let draws: Vec<_> = (0..400).map(|seed| error.draw(seed, "lidar")).collect();
    for axis in 0..3 {
        for (what, sigma, values) in [
            (
                "offset",
                error.sigma_m,
                draws
                    .iter()
                    .map(|d| d.translation.vector[axis])
                    .collect::<Vec<_>>(),
            ),
            (
                "rotation",
                error.sigma_deg.to_radians(),
                draws
                    .iter()
                    .map(|d| d.rotation.scaled_axis()[axis])
                    .collect(),
            ),
        ] {
            let n = values.len() as f64;
            let mean = values.iter().sum::<f64>() / n;
            let sd = (values.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / (n - 1.0)).sqrt();
            assert!(
                (sd / sigma - 1.0).abs() < 0.1,
                "{what} axis {axis}: σ {sd} for {sigma}"
            );
            assert!(
                mean.abs() < 4.0 * sigma / n.sqrt(),
                "{what} axis {axis}: mean {mean}"
            );
        }
    }
    assert_ne!(
        error.draw(3, "lidar"),
        error.draw(3, "imu"),
        "each sensor draws its own error"
    );
}

/// The IMU turned by its drawn error measures the still robot's specific force in its own,
/// turned frame (`a_true = R⁻¹ a_nominal`), while the configuration the systems read keeps
/// the nominal mount. Under `ideal`, so only the mount differs.
#[test]
fn a_turned_imu_measures_in_its_turned_frame_and_the_systems_keep_the_nominal_mount() {
    let nominal = SimConfig::from_toml_str("profile = \"ideal\"\n", "ideal").expect("world");
    let mut turned = nominal.clone();
    turned.sensors.imu.mount_error = MountError {
        sigma_m: 0.0,
        sigma_deg: 2.0,
    };
    assert_eq!(nominal.profile, Profile::Ideal);
    let seed = 5;
    let first = |cfg: &SimConfig| {
        let sim = Simulation::new(cfg, "s0", seed).expect("simulation");
        let placed = sim.placed_sensors().imu.mount;
        let imu = SensorSet {
            imu: true,
            ..SensorSet::default()
        };
        let accel = sim
            .stream(imu)
            .find_map(|m| match m {
                Message::Imu(s) => Some(s.accel_mps2),
                _ => None,
            })
            .expect("an IMU sample");
        (placed, accel, sim.config.sensors.imu.mount)
    };
    let (placed_n, a_nominal, told_n) = first(&nominal);
    let (placed_t, a_turned, told_t) = first(&turned);
    assert_eq!(
        placed_n, nominal.sensors.imu.mount,
        "no error: where it was"
    );
    assert_eq!(told_t, told_n, "the systems are told the nominal mount");
    assert_ne!(placed_t, told_t, "the turned IMU sits elsewhere");
    let r = turned.sensors.imu.mount_error.draw(seed, "imu").rotation;
    let angle = r.angle().to_degrees();
    assert!(angle > 0.5, "a draw of σ 2° per axis turned it by {angle}°");
    let expected = r.inverse() * a_nominal;
    assert!(
        (a_turned - expected).norm() < 1e-6,
        "{a_turned:?} against {expected:?}"
    );
    assert!(
        (a_turned - a_nominal).norm() > 0.05,
        "the turn shows in the reading"
    );
}
