//! A plugin that fails on purpose, to prove that one broken plugin costs one run and not
//! the benchmark. Parameters: `fault = "none" | "panic" | "abort" | "segfault" | "hang" |
//! "alloc" | "nan"`, `after = N` (the message at which it strikes, default 20). Until then
//! it behaves as a (poor) odometry that echoes the wheel odometry pose, taking `work_ms`
//! milliseconds over each message (default 0: a slow system, for bounded queues).

// The segfault fault writes through a null pointer: that is its whole point.
#![allow(unsafe_code)]

use plugin_api::{
    Parameters, PluginError, Pose, Requirements, Rig, SensorKind, SlamOutput, SlamSystem,
    WheelOdometry, export_plugin,
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
}

impl FaultPlugin {
    fn strike(&mut self) -> Option<Pose> {
        match self.config.fault {
            Fault::None | Fault::Nan => None,
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
        Requirements::online(&[SensorKind::WheelOdometry])
    }

    fn new(config_toml: &str, _rig: &Rig) -> Result<Self, PluginError> {
        let config = Config::from_toml(config_toml).map_err(PluginError::new)?;
        Ok(Self {
            config,
            seen: 0,
            trajectory: Vec::new(),
            hoard: Vec::new(),
        })
    }

    fn on_wheel_odometry(&mut self, odom: &WheelOdometry) -> Result<Option<Pose>, PluginError> {
        self.seen += 1;
        if self.config.work_ms > 0 {
            std::thread::sleep(std::time::Duration::from_millis(self.config.work_ms));
        }
        if self.seen == self.config.after {
            self.strike();
        }
        let mut pose = Pose {
            stamp_ns: odom.stamp_ns,
            ..odom.odom_from_base
        };
        if self.config.fault == Fault::Nan && self.seen >= self.config.after {
            pose.translation[0] = f64::NAN;
        }
        self.trajectory.push(pose);
        Ok(Some(pose))
    }

    fn finish(&mut self) -> Result<SlamOutput, PluginError> {
        Ok(SlamOutput {
            trajectory: std::mem::take(&mut self.trajectory),
            ..SlamOutput::default()
        })
    }
}

export_plugin!(FaultPlugin);
