//! The only crate a vinebench plugin author needs.
//!
//! Implement [`SlamSystem`] for your type and call [`export_plugin!`]: the crate builds a
//! `cdylib` that the `vinebench` host loads by name or path, feeds with sensor messages in
//! time order, and evaluates. The ABI (abi_stable) stays inside this crate: you see plain
//! Rust types, slices, `nalgebra` poses and `Result`s.
//!
//! Systems in C, C++ or any language that exports a C function implement the C ABI of
//! `include/vinebench_plugin.h` instead (one table of plain C data and function pointers);
//! the same loader takes both kinds of library and the host runs them alike.
//!
//! ```ignore
//! use plugin_api::{export_plugin, PluginError, Requirements, Rig, SensorKind, SlamOutput, SlamSystem, WheelOdometry, Pose};
//!
//! struct Odometry { poses: Vec<Pose> }
//!
//! impl SlamSystem for Odometry {
//!     const NAME: &'static str = "my-odometry";
//!     const VERSION: &'static str = env!("CARGO_PKG_VERSION");
//!     fn requirements() -> Requirements { Requirements::online(&[SensorKind::WheelOdometry]) }
//!     fn new(_config: &str, _rig: &Rig) -> Result<Self, PluginError> { Ok(Self { poses: Vec::new() }) }
//!     fn on_wheel_odometry(&mut self, m: &WheelOdometry) -> Result<Option<Pose>, PluginError> {
//!         let pose = Pose { stamp_ns: m.stamp_ns, ..m.odom_from_base };
//!         self.poses.push(pose);
//!         Ok(Some(pose))
//!     }
//!     fn finish(&mut self) -> Result<SlamOutput, PluginError> {
//!         Ok(SlamOutput { trajectory: std::mem::take(&mut self.poses), ..SlamOutput::default() })
//!     }
//! }
//!
//! export_plugin!(Odometry);
//! ```

// abi_stable's derives and `#[sabi_trait]` expand to unsafe code (raw vtables, FFI
// function pointers); it is confined to the generated glue in `ffi`, the loader and the C
// ABI's host side (`c_abi`).
#![allow(unsafe_code)]

mod c_abi;
mod ffi;
mod loader;
mod messages;
mod parameters;
mod rig;
mod stages;
mod system;

pub use loader::{Door, LoadError, LoadedPlugin, PluginInstance, load};
pub use messages::{
    Gnss, GnssStatus, Imu, LaserScan, LidarPoint, PointCloud, Pose, RgbdFrame, WheelOdometry,
    gray_from_rgb,
};
pub use parameters::Parameters;
pub use rig::{Lens, Pinhole, Rig, SensorKind, SensorSpec};
pub use stages::Stages;
pub use system::{
    Event, EventKind, GRID_MAP_FORMAT, GRID_MAP_VERSION, InitialGuess, MapStart, Mode,
    OccupancyGrid, PluginError, PoseStatus, Requirements, SavedMap, SlamOutput, SlamSystem,
};

/// This crate's version: a Rust plugin loads when its plugin-api has the host's
/// `major.minor` (docs/plugin-contract.md, "Versions").
pub const API_VERSION: &str = env!("CARGO_PKG_VERSION");

/// The contract's revision, the same number in all three doors (the C header's
/// `VB_ABI_REVISION`, the Python bridge's `API_REVISION`): how many rounds of appended
/// calls and fields it has had (docs/plugin-contract.md, "Versions").
pub const ABI_REVISION: u32 = c_abi::ABI_REVISION;

/// The C door's host side driven with arbitrary values (`fuzz/`); not part of the API.
#[doc(hidden)]
pub mod __fuzzing {
    pub use crate::c_abi::fuzzing::{c_answers, c_output};
}

/// Used by [`export_plugin!`]; not part of the API.
#[doc(hidden)]
pub mod __private {
    pub use crate::ffi::{PluginModuleRef, module};
    pub use abi_stable;
}

include!(concat!(env!("OUT_DIR"), "/export_plugin.rs"));
