//! The plugin: each message becomes robot_localization's measurements and goes through the
//! filter (with its lagged-data history); each wheel odometry message answers with the
//! filter's pose.

use std::collections::VecDeque;

use nalgebra::UnitQuaternion;
use plugin_api::{
    Event, EventKind, Gnss, Imu, Parameters, PluginError, Pose, Requirements, Rig, SensorKind,
    SlamOutput, SlamSystem, WheelOdometry, export_plugin,
};

use crate::config::Config;
use crate::filter::{Ekf, Outcome};
use crate::history::LaggedFilter;
use crate::navsat::NavSat;
use crate::sensors::{ImuModel, WheelOdometryModel};
use crate::state::{self, PITCH, ROLL, StateVector, YAW, wrap_angle};

/// How long IMU orientations are kept to find the one at a fix's stamp.
const ORIENTATION_BUFFER_NS: i64 = 2_000_000_000;
/// The farthest an orientation may be from a fix's stamp to be used for it.
const ORIENTATION_MAX_GAP_NS: u64 = 100_000_000;

/// Why GNSS is not fused (yet).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Heading {
    /// The IMU reports orientations (or `use_odometry_yaw`): align when one is at hand.
    Expected,
    /// No absolute heading will come: GNSS is never fused (said once).
    Never { said: bool },
}

/// robot_localization's EKF with navsat_transform, as a vinebench system.
#[derive(Debug)]
pub struct EkfLocalization {
    cfg: Config,
    filter: LaggedFilter,
    odometry: WheelOdometryModel,
    imu: ImuModel,
    /// `None` where the rig has no receiver.
    navsat: Option<NavSat>,
    heading: Heading,
    /// Recent absolute orientations `world_from_base` from the IMU, oldest first.
    orientations: VecDeque<(i64, UnitQuaternion<f64>)>,
    trajectory: Vec<Pose>,
    events: Vec<Event>,
}

impl EkfLocalization {
    /// The IMU's orientation of the base nearest to `stamp_ns`, if one is near.
    fn orientation_at(&self, stamp_ns: i64) -> Option<UnitQuaternion<f64>> {
        self.orientations
            .iter()
            .min_by_key(|(t, _)| t.abs_diff(stamp_ns))
            .filter(|(t, _)| t.abs_diff(stamp_ns) <= ORIENTATION_MAX_GAP_NS)
            .map(|(_, q)| *q)
    }

    /// The base's attitude `odom_r_base` for the lever arm at `stamp_ns`: the filter's yaw,
    /// and its roll and pitch, or in `two_d_mode` (where the filter holds them at 0) the
    /// IMU's when it reports them.
    fn attitude(&self, state: &StateVector, stamp_ns: i64) -> UnitQuaternion<f64> {
        let (roll, pitch) = if self.cfg.two_d_mode {
            self.orientation_at(stamp_ns).map_or((0.0, 0.0), |q| {
                let (r, p, _) = q.euler_angles();
                (r, p)
            })
        } else {
            (state[ROLL], state[PITCH])
        };
        UnitQuaternion::from_euler_angles(roll, pitch, state[YAW])
    }

    /// The base's attitude in ENU with an absolute heading at `stamp_ns`, if one is known
    /// (navsat_transform's IMU, or with `use_odometry_yaw` the filter's own).
    fn enu_attitude(&self, state: &StateVector, stamp_ns: i64) -> Option<UnitQuaternion<f64>> {
        let (roll, pitch, yaw) = if self.cfg.use_odometry_yaw {
            (state[ROLL], state[PITCH], state[YAW])
        } else {
            self.orientation_at(stamp_ns)?.euler_angles()
        };
        let yaw = wrap_angle(yaw + self.cfg.magnetic_declination_radians + self.cfg.yaw_offset);
        Some(UnitQuaternion::from_euler_angles(roll, pitch, yaw))
    }

    fn reject(&mut self, stamp_ns: i64, detail: String) {
        self.events
            .push(Event::new(stamp_ns, EventKind::GnssRejected, detail));
    }

    fn filter_pose(&self) -> Result<Pose, PluginError> {
        let ekf = &self.filter.ekf;
        if !ekf.state.iter().all(|v| v.is_finite()) {
            return Err(PluginError::new(
                "ekf: the filter's state is not finite (a bug: every input is checked)",
            ));
        }
        Ok(Pose::new(ekf.last_measurement_ns, &state::pose(&ekf.state)))
    }
}

impl SlamSystem for EkfLocalization {
    const NAME: &'static str = "ekf";
    const VERSION: &'static str = env!("CARGO_PKG_VERSION");

    fn requirements() -> Requirements {
        Requirements::online(&[SensorKind::WheelOdometry, SensorKind::Imu, SensorKind::Gnss])
    }

    fn new(config_toml: &str, rig: &Rig) -> Result<Self, PluginError> {
        let cfg = Config::from_toml(config_toml).map_err(PluginError::new)?;
        let ekf = Ekf::new(
            cfg.process_noise().map_err(PluginError::new)?,
            cfg.initial_covariance().map_err(PluginError::new)?,
            cfg.use_dynamic_process_noise_covariance,
        );
        let imu_spec = rig.first(SensorKind::Imu);
        let navsat = match rig.first(SensorKind::Gnss) {
            Some(gnss) => {
                let mount = gnss.base_from_sensor();
                if !mount.translation.vector.iter().all(|v| v.is_finite()) {
                    return Err(PluginError::new(
                        "the GNSS receiver's mount (its lever arm) is not finite",
                    ));
                }
                Some(NavSat::new(
                    &mount,
                    cfg.two_d_mode,
                    cfg.gnss0_rejection_threshold,
                ))
            }
            None => None,
        };
        let reports_orientation = imu_spec
            .and_then(|s| s.intrinsics.get("reports_orientation"))
            .is_some_and(|&v| v == 1.0);
        let heading = if reports_orientation || cfg.use_odometry_yaw {
            Heading::Expected
        } else {
            Heading::Never { said: false }
        };
        Ok(Self {
            filter: LaggedFilter::new(ekf, cfg.smooth_lagged_data, cfg.history_length),
            odometry: WheelOdometryModel::new(rig.first(SensorKind::WheelOdometry), &cfg),
            imu: ImuModel::new(imu_spec, &cfg),
            navsat,
            heading,
            orientations: VecDeque::new(),
            trajectory: Vec::new(),
            events: Vec::new(),
            cfg,
        })
    }

    fn on_imu(&mut self, imu: &Imu) -> Result<Option<Pose>, PluginError> {
        if let Some(q) = self.imu.base_orientation(imu) {
            self.orientations.push_back((imu.stamp_ns, q));
            while self
                .orientations
                .front()
                .is_some_and(|(t, _)| *t < imu.stamp_ns.saturating_sub(ORIENTATION_BUFFER_NS))
            {
                self.orientations.pop_front();
            }
        }
        let replay = self.filter.rewind(imu.stamp_ns);
        let state = self.filter.ekf.state;
        let measurements = self.imu.measurements(imu, &state);
        self.filter.integrate(measurements, replay);
        Ok(None)
    }

    fn on_wheel_odometry(&mut self, odom: &WheelOdometry) -> Result<Option<Pose>, PluginError> {
        let replay = self.filter.rewind(odom.stamp_ns);
        let m = self.odometry.measurement(odom);
        self.filter.integrate(vec![m], replay);
        if !self.filter.ekf.initialized {
            return Ok(None);
        }
        let pose = self.filter_pose()?;
        if self
            .trajectory
            .last()
            .is_some_and(|last| last.stamp_ns >= pose.stamp_ns)
        {
            return Ok(None);
        }
        self.trajectory.push(pose);
        Ok(Some(pose))
    }

    fn on_gnss(&mut self, gnss: &Gnss) -> Result<Option<Pose>, PluginError> {
        if self.navsat.is_none() {
            return Ok(None);
        }
        let stamp = gnss.stamp_ns;
        if let Some(problem) = gnss.problem() {
            self.reject(stamp, format!("{problem} ({} fix)", gnss.status.name()));
            return Ok(None);
        }
        let (Some(antenna), Some(covariance)) = (gnss.position(), gnss.covariance()) else {
            return Ok(None); // `problem` said why; unreachable.
        };
        if let Heading::Never { said } = self.heading {
            if !said {
                self.heading = Heading::Never { said: true };
                self.reject(
                    stamp,
                    "navsat_transform needs an absolute heading to align the datum with odom: \
                     the IMU reports no orientation and use_odometry_yaw is false, so no GNSS \
                     fix is fused in this run"
                        .into(),
                );
            }
            return Ok(None);
        }
        if !self.filter.ekf.initialized {
            self.reject(stamp, "a fix before the filter's first measurement".into());
            return Ok(None);
        }
        let replay = self.filter.rewind(stamp);
        let state = self.filter.ekf.state_at(stamp);
        let attitude = self.attitude(&state, stamp);
        let enu_attitude = self.enu_attitude(&state, stamp);
        let Some(navsat) = self.navsat.as_mut() else {
            return Ok(None);
        };
        let measurement = if navsat.odom_from_enu().is_some() {
            navsat.measurement(stamp, &antenna, &covariance, &attitude)
        } else {
            match enu_attitude {
                Some(enu_r_base) => navsat.align(&antenna, &enu_r_base, &state),
                None => {
                    self.filter.integrate(Vec::new(), replay);
                    self.reject(
                        stamp,
                        "no IMU orientation yet to align the datum with odom".into(),
                    );
                    return Ok(None);
                }
            }
            None
        };
        let fresh: Vec<_> = measurement.into_iter().collect();
        let outcomes = self.filter.integrate(fresh, replay);
        if let Some(Outcome::Rejected {
            squared_mahalanobis,
            threshold,
        }) = outcomes.first().copied()
        {
            self.reject(
                stamp,
                format!(
                    "Mahalanobis distance {:.2} beyond gnss0_rejection_threshold {threshold} ({} fix, {} satellites)",
                    squared_mahalanobis.sqrt(),
                    gnss.status.name(),
                    gnss.satellites
                ),
            );
        }
        Ok(None)
    }

    fn finish(&mut self) -> Result<SlamOutput, PluginError> {
        Ok(SlamOutput {
            trajectory: self.trajectory.clone(),
            events: std::mem::take(&mut self.events),
            ..SlamOutput::default()
        })
    }
}

export_plugin!(EkfLocalization);
