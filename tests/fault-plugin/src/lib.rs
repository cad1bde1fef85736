//! A plugin that fails on purpose, to prove that one broken plugin costs one run and not
//! the benchmark. Parameters: `fault = "none" | "panic" | "abort" | "segfault" | "hang" |
//! "alloc" | "nan"`, `after = N` (the message at which it strikes, default 20). Until then
//! it behaves as a (poor) odometry that echoes the wheel odometry pose, taking `work_ms`
//! milliseconds over each message (default 0: a slow system, for bounded queues).
//!
//! It is also the Rust door's localisation fixture (revision 4), as `c_odometry.c` is the
//! C door's and `vinebench_plugin.WheelOdometry` the Python door's: it saves its last echoed
//! pose as an "odometry-end" version 1 map (x, y, yaw, little-endian f64), and started from
//! one it echoes the odometry moved to the initial guess (else as is), searching for its
//! first 10 poses. `fault = "map"` makes it refuse any map.

// The segfault fault writes through a null pointer: that is its whole point.
#![allow(unsafe_code)]

use plugin_api::{
    MapStart, Parameters, PluginError, Pose, PoseStatus, Requirements, Rig, SavedMap, SensorKind,
    SlamOutput, SlamSystem, WheelOdometry, export_plugin,
};
use serde::Deserialize;

#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize, Default)]
#[serde(rename_all = "lowercase")]
enum Fault {
    #[default]
    None,
    Panic,
    Abort,
    Segfault,
    Hang,
    Alloc,
    Nan,
    /// Refuses any map it is started from.
    Map,
}

#[derive(Debug, Deserialize)]
#[serde(default, deny_unknown_fields)]
struct Config {
    fault: Fault,
    after: usize,
    work_ms: u64,
}

impl Parameters for Config {}

impl Default for Config {
    fn default() -> Self {
        Self {
            fault: Fault::None,
            after: 20,
            work_ms: 0,
        }
    }
}

#[derive(Debug)]
pub struct FaultPlugin {
    config: Config,
    seen: usize,
    trajectory: Vec<Pose>,
    hoard: Vec<Vec<u8>>,
    /// Localising: `map_from_odom` (the initial guess, or the identity).
    map_from_odom: Option<nalgebra::Isometry3<f64>>,
}

/// Poses answered `Searching` when started from a map.
const SEARCHING_POSES: usize = 10;

impl FaultPlugin {
    fn strike(&mut self) -> Option<Pose> {
        match self.config.fault {
            Fault::None | Fault::Nan | Fault::Map => None,
            Fault::Panic => panic!("fault plugin: deliberate panic"),
            Fault::Abort => std::process::abort(),
            Fault::Segfault => {
                // SAFETY: none; this is the deliberate invalid write the fault exists for.
                unsafe { std::ptr::null_mut::<u64>().write_volatile(0xdead) };
                None
            }
            Fault::Hang => loop {
                std::thread::sleep(std::time::Duration::from_secs(1));
            },
            Fault::Alloc => loop {
                // Touch every page so the memory is really used.
                self.hoard.push(vec![1u8; 64 << 20]);
            },
        }
    }
}

impl SlamSystem for FaultPlugin {
    const NAME: &'static str = "fault";
    const VERSION: &'static str = env!("CARGO_PKG_VERSION");

    fn requirements() -> Requirements {
        Requirements::online(&[SensorKind::WheelOdometry]).localizing()
    }

    fn new(config_toml: &str, _rig: &Rig) -> Result<Self, PluginError> {
        let config = Config::from_toml(config_toml).map_err(PluginError::new)?;
        Ok(Self {
            config,
            seen: 0,
            trajectory: Vec::new(),
            hoard: Vec::new(),
            map_from_odom: None,
        })
    }

    fn localize(config_toml: &str, rig: &Rig, start: &MapStart<'_>) -> Result<Self, PluginError> {
        let mut system = Self::new(config_toml, rig)?;
        if system.config.fault == Fault::Map
            || (start.format, start.format_version, start.map.len()) != ("odometry-end", 1, 24)
        {
            return Err(PluginError::new(
                "fault: not an odometry-end version 1 map of 24 bytes",
            ));
        }
        system.map_from_odom = Some(
            start
                .initial_guess
                .and_then(|g| g.map_from_base.isometry())
                .unwrap_or_else(nalgebra::Isometry3::identity),
        );
        Ok(system)
    }

    fn status(&self) -> PoseStatus {
        if self.map_from_odom.is_some() && self.trajectory.len() <= SEARCHING_POSES {
            PoseStatus::Searching
        } else {
            PoseStatus::Localized
        }
    }

    fn on_wheel_odometry(&mut self, odom: &WheelOdometry) -> Result<Option<Pose>, PluginError> {
        self.seen += 1;
        if self.config.work_ms > 0 {
            std::thread::sleep(std::time::Duration::from_millis(self.config.work_ms));
        }
        if self.seen == self.config.after {
            self.strike();
        }
        let mut pose = match (self.map_from_odom, odom.odom_from_base.isometry()) {
            (Some(map_from_odom), Some(odom_from_base)) => {
                Pose::new(odom.stamp_ns, &(map_from_odom * odom_from_base))
            }
            _ => Pose {
                stamp_ns: odom.stamp_ns,
                ..odom.odom_from_base
            },
        };
        if self.config.fault == Fault::Nan && self.seen >= self.config.after {
            pose.translation[0] = f64::NAN;
        }
        self.trajectory.push(pose);
        Ok(Some(pose))
    }

    fn finish(&mut self) -> Result<SlamOutput, PluginError> {
        let saved_map = self.trajectory.last().and_then(Pose::isometry).map(|end| {
            let (_, _, yaw) = end.rotation.euler_angles();
            let t = end.translation.vector;
            SavedMap {
                format: "odometry-end".into(),
                version: 1,
                bytes: [t.x, t.y, yaw]
                    .iter()
                    .flat_map(|v| v.to_le_bytes())
                    .collect(),
            }
        });
        Ok(SlamOutput {
            trajectory: std::mem::take(&mut self.trajectory),
            saved_map,
            ..SlamOutput::default()
        })
    }
}

export_plugin!(FaultPlugin);
