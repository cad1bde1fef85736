//! The host side of the C ABI (`include/vinebench_plugin.h`): plugins written in C, C++ or
//! anything that exports `vinebench_plugin_v1`, a table of plain C data and function
//! pointers. The mirrors here have the header's layouts (`#[repr(C)]`, field for field;
//! `Pose`, `Imu`, `WheelOdometry` and `LidarPoint` are the Rust API's own types, whose
//! layouts are the header's). The loader ([`crate::loader::load`]) tries this symbol first
//! and falls back to abi_stable's root module; both kinds then run the same way.

// The mirrors are plain data for the FFI.
#![allow(missing_debug_implementations)]

use std::ffi::{CStr, CString, c_char, c_void};
use std::path::Path;

use crate::messages::{Imu, LaserScan, LidarPoint, PointCloud, Pose, RgbdFrame, WheelOdometry};
use crate::rig::Rig;
use crate::system::{OccupancyGrid, PluginError, Requirements, SlamOutput};

/// The header's `VB_ABI_VERSION`.
pub const ABI_VERSION: u32 = 1;
/// The symbol a C plugin exports.
pub const SYMBOL: &[u8] = b"vinebench_plugin_v1\0";

const NO_POSE: i32 = 0;
const POSE: i32 = 1;

#[repr(C)]
struct PointCloudC {
    stamp_ns: i64,
    sensor: *const c_char,
    sensor_len: usize,
    points: *const LidarPoint,
    n_points: usize,
}

#[repr(C)]
struct LaserScanC {
    stamp_ns: i64,
    sensor: *const c_char,
    sensor_len: usize,
    angle_min_rad: f32,
    angle_increment_rad: f32,
    time_increment_s: f32,
    range_min_m: f32,
    range_max_m: f32,
    ranges_m: *const f32,
    n_ranges: usize,
    intensities: *const f32,
    n_intensities: usize,
}

#[repr(C)]
struct RgbdFrameC {
    stamp_ns: i64,
    sensor: *const c_char,
    sensor_len: usize,
    width: u32,
    height: u32,
    rgb: *const u8,
    rgb_len: usize,
    depth_m: *const f32,
    depth_len: usize,
    intrinsics: [f64; 4],
}

#[repr(C)]
struct GridC {
    resolution_m: f64,
    origin: [f64; 3],
    width: u32,
    height: u32,
    cells: *const i8,
}

#[repr(C)]
struct OutputC {
    trajectory: *const Pose,
    n_trajectory: usize,
    map_xyz: *const f32,
    n_map_points: usize,
    grid: *const GridC,
    events_toml: *const c_char,
}

type Callback<M> = Option<unsafe extern "C" fn(*mut c_void, *const M, *mut Pose) -> i32>;

/// The header's `vb_plugin`.
#[repr(C)]
struct Table {
    abi_version: u32,
    struct_size: u32,
    name: *const c_char,
    version: *const c_char,
    requirements_toml: *const c_char,
    create: Option<unsafe extern "C" fn(*const c_char, *const c_char) -> *mut c_void>,
    destroy: Option<unsafe extern "C" fn(*mut c_void)>,
    last_error: Option<unsafe extern "C" fn(*mut c_void) -> *const c_char>,
    on_imu: Callback<Imu>,
    on_wheel_odometry: Callback<WheelOdometry>,
    on_point_cloud: Callback<PointCloudC>,
    on_laser_scan: Callback<LaserScanC>,
    on_rgbd: Callback<RgbdFrameC>,
    finish: Option<unsafe extern "C" fn(*mut c_void, *mut OutputC) -> i32>,
}

/// A loaded C plugin's table: valid as long as its library stays loaded, which the loader
/// keeps for the life of the process.
#[derive(Clone, Copy)]
pub struct CPlugin {
    table: &'static Table,
}

/// `text` of a NUL-terminated string the plugin owns; `what` names it in errors.
///
/// # Safety
/// `p` is NULL or points to a NUL-terminated string valid for this call.
unsafe fn text(p: *const c_char, what: &str) -> Result<String, String> {
    if p.is_null() {
        return Err(format!("{what} is NULL"));
    }
    // SAFETY: non-null and NUL-terminated, as the header requires.
    let s = unsafe { CStr::from_ptr(p) };
    s.to_str()
        .map(str::to_owned)
        .map_err(|_| format!("{what} is not UTF-8"))
}

/// What [`CPlugin::open`] learnt: the table with its name, version and requirements.
pub struct Opened {
    pub plugin: CPlugin,
    pub name: String,
    pub version: String,
    pub requirements: Requirements,
}

impl CPlugin {
    /// The table of the C plugin library at `path`, `Ok(None)` if it exports no
    /// `vinebench_plugin_v1` (then it may be a Rust plugin). The library stays loaded.
    pub fn open(path: &Path) -> Result<Option<Opened>, String> {
        // SAFETY: loading a library runs its initialisers; a plugin library is code the user
        // chose to run, in a worker process of its own.
        let library = unsafe { libloading::Library::new(path) }.map_err(|e| e.to_string())?;
        // SAFETY: the symbol, where present, has the header's signature.
        let entry = match unsafe { library.get::<unsafe extern "C" fn() -> *const Table>(SYMBOL) } {
            Ok(f) => *f,
            Err(_) => return Ok(None),
        };
        // Kept loaded for the process's life: the table and its functions live in it.
        std::mem::forget(library);
        // SAFETY: the entry point takes nothing and returns a pointer to a static table.
        let table = unsafe { entry() };
        if table.is_null() {
            return Err("vinebench_plugin_v1() returned NULL".into());
        }
        // SAFETY: the first two fields exist in every version of the table.
        let (abi, size) = unsafe { ((*table).abi_version, (*table).struct_size) };
        if abi != ABI_VERSION {
            return Err(format!(
                "built against the C ABI version {abi}, but this vinebench has version \
                 {ABI_VERSION}; rebuild it against this vinebench's vinebench_plugin.h"
            ));
        }
        if (size as usize) < size_of::<Table>() {
            return Err(format!(
                "its vb_plugin is {size} bytes, smaller than version {ABI_VERSION}'s {}",
                size_of::<Table>()
            ));
        }
        // SAFETY: checked non-null, of this version and at least this size; static.
        let table: &'static Table = unsafe { &*table };
        // SAFETY: the strings are the table's, NUL-terminated and static.
        let (name, version, requirements) = unsafe {
            (
                text(table.name, "name")?,
                text(table.version, "version")?,
                text(table.requirements_toml, "requirements_toml")?,
            )
        };
        let requirements: Requirements = toml::from_str(&requirements)
            .map_err(|e| format!("unreadable requirements_toml: {}", e.message()))?;
        for (present, what) in [
            (table.create.is_some(), "create"),
            (table.destroy.is_some(), "destroy"),
            (table.last_error.is_some(), "last_error"),
            (table.finish.is_some(), "finish"),
        ] {
            if !present {
                return Err(format!("its table has no {what} function"));
            }
        }
        Ok(Some(Opened {
            plugin: CPlugin { table },
            name,
            version,
            requirements,
        }))
    }

    /// Creates the system with its parameters and the rig.
    pub fn create(&self, config_toml: &str, rig: &Rig) -> Result<CInstance, PluginError> {
        let nul = |what: &str| PluginError(format!("the {what} contains a NUL byte"));
        let config = CString::new(config_toml).map_err(|_| nul("parameter table"))?;
        let rig = CString::new(rig.to_toml()).map_err(|_| nul("rig"))?;
        let create = self.table.create.expect("checked at load");
        // SAFETY: both strings are NUL-terminated and live through the call.
        let this = unsafe { create(config.as_ptr(), rig.as_ptr()) };
        if this.is_null() {
            return Err(PluginError(self.error(std::ptr::null_mut(), "create")));
        }
        Ok(CInstance {
            table: self.table,
            this,
        })
    }

    /// The plugin's last error of `this` (NULL: of `create`), or a stand-in naming `call`.
    fn error(&self, this: *mut c_void, call: &str) -> String {
        let last_error = self.table.last_error.expect("checked at load");
        // SAFETY: `this` is NULL or a live instance; the string lives until the next call.
        let message = unsafe { text(last_error(this), "last_error") };
        match message {
            Ok(m) if !m.trim().is_empty() => m.lines().next().unwrap_or("").trim().to_owned(),
            _ => format!("{call} failed without an error message"),
        }
    }
}

/// A created C plugin.
pub struct CInstance {
    table: &'static Table,
    this: *mut c_void,
}

// SAFETY: the host drives an instance from one thread at a time, as the header promises the
// plugin; it may move between threads between calls.
unsafe impl Send for CInstance {}

impl Drop for CInstance {
    fn drop(&mut self) {
        if let Some(destroy) = self.table.destroy {
            // SAFETY: `this` came from `create` and is destroyed once.
            unsafe { destroy(self.this) };
        }
    }
}

impl CInstance {
    fn error(&self, call: &str) -> PluginError {
        PluginError(CPlugin { table: self.table }.error(self.this, call))
    }

    /// Calls `f` with `message`, turning its return value into the Rust API's.
    fn call<M>(
        &mut self,
        f: Callback<M>,
        message: &M,
        what: &str,
    ) -> Result<Option<Pose>, PluginError> {
        let Some(f) = f else { return Ok(None) };
        let mut estimate = Pose {
            stamp_ns: 0,
            translation: [0.0; 3],
            rotation_xyzw: [0.0, 0.0, 0.0, 1.0],
        };
        // SAFETY: `this` is live, `message` and `estimate` are valid for the call.
        match unsafe { f(self.this, message, &mut estimate) } {
            NO_POSE => Ok(None),
            POSE => Ok(Some(estimate)),
            _ => Err(self.error(what)),
        }
    }

    pub fn on_imu(&mut self, imu: &Imu) -> Result<Option<Pose>, PluginError> {
        self.call(self.table.on_imu, imu, "on_imu")
    }

    pub fn on_wheel_odometry(&mut self, odom: &WheelOdometry) -> Result<Option<Pose>, PluginError> {
        self.call(self.table.on_wheel_odometry, odom, "on_wheel_odometry")
    }

    pub fn on_point_cloud(&mut self, c: &PointCloud<'_>) -> Result<Option<Pose>, PluginError> {
        let m = PointCloudC {
            stamp_ns: c.stamp_ns,
            sensor: c.sensor.as_ptr().cast(),
            sensor_len: c.sensor.len(),
            points: c.points.as_ptr(),
            n_points: c.points.len(),
        };
        self.call(self.table.on_point_cloud, &m, "on_point_cloud")
    }

    pub fn on_laser_scan(&mut self, s: &LaserScan<'_>) -> Result<Option<Pose>, PluginError> {
        let m = LaserScanC {
            stamp_ns: s.stamp_ns,
            sensor: s.sensor.as_ptr().cast(),
            sensor_len: s.sensor.len(),
            angle_min_rad: s.angle_min_rad,
            angle_increment_rad: s.angle_increment_rad,
            time_increment_s: s.time_increment_s,
            range_min_m: s.range_min_m,
            range_max_m: s.range_max_m,
            ranges_m: s.ranges_m.as_ptr(),
            n_ranges: s.ranges_m.len(),
            intensities: s.intensities.as_ptr(),
            n_intensities: s.intensities.len(),
        };
        self.call(self.table.on_laser_scan, &m, "on_laser_scan")
    }

    pub fn on_rgbd(&mut self, f: &RgbdFrame<'_>) -> Result<Option<Pose>, PluginError> {
        let m = RgbdFrameC {
            stamp_ns: f.stamp_ns,
            sensor: f.sensor.as_ptr().cast(),
            sensor_len: f.sensor.len(),
            width: f.width,
            height: f.height,
            rgb: f.rgb.as_ptr(),
            rgb_len: f.rgb.len(),
            depth_m: f.depth_m.as_ptr(),
            depth_len: f.depth_m.len(),
            intrinsics: f.intrinsics,
        };
        self.call(self.table.on_rgbd, &m, "on_rgbd")
    }

    /// The plugin's output, copied out of its memory.
    pub fn finish(&mut self) -> Result<SlamOutput, PluginError> {
        let finish = self.table.finish.expect("checked at load");
        let mut o = OutputC {
            trajectory: std::ptr::null(),
            n_trajectory: 0,
            map_xyz: std::ptr::null(),
            n_map_points: 0,
            grid: std::ptr::null(),
            events_toml: std::ptr::null(),
        };
        // SAFETY: `this` is live and `o` is valid for the call.
        if unsafe { finish(self.this, &mut o) } != 0 {
            return Err(self.error("finish"));
        }
        let bad = |what: &str| PluginError(format!("finish: {what}"));
        // SAFETY: the header makes the plugin keep these arrays, of these lengths, alive
        // until `destroy`; each is checked non-null before it is read.
        let slice = |p: *const Pose, n: usize| -> &[Pose] {
            if n == 0 {
                &[]
            } else {
                unsafe { std::slice::from_raw_parts(p, n) }
            }
        };
        if o.n_trajectory > 0 && o.trajectory.is_null() {
            return Err(bad("trajectory is NULL with n_trajectory > 0"));
        }
        let trajectory = slice(o.trajectory, o.n_trajectory).to_vec();
        let map = if o.map_xyz.is_null() {
            None
        } else {
            // SAFETY: as above, 3 floats a point.
            let xyz = unsafe { std::slice::from_raw_parts(o.map_xyz, 3 * o.n_map_points) };
            Some(xyz.chunks_exact(3).map(|p| [p[0], p[1], p[2]]).collect())
        };
        let grid = if o.grid.is_null() {
            None
        } else {
            // SAFETY: non-null, a vb_grid the plugin keeps alive.
            let g = unsafe { &*o.grid };
            let n = g.width as usize * g.height as usize;
            if n > 0 && g.cells.is_null() {
                return Err(bad("grid cells are NULL"));
            }
            // SAFETY: `n` cells, as the header requires.
            let cells = if n == 0 {
                Vec::new()
            } else {
                unsafe { std::slice::from_raw_parts(g.cells, n) }.to_vec()
            };
            Some(OccupancyGrid {
                resolution_m: g.resolution_m,
                origin: g.origin,
                width: g.width,
                height: g.height,
                cells,
            })
        };
        let events = if o.events_toml.is_null() {
            Vec::new()
        } else {
            // SAFETY: NUL-terminated, kept alive by the plugin.
            let toml_text = unsafe { text(o.events_toml, "events_toml") }.map_err(|e| bad(&e))?;
            crate::ffi::events_from_toml(&toml_text).map_err(|e| bad(&e))?
        };
        Ok(SlamOutput {
            trajectory,
            map,
            grid,
            events,
        })
    }
}
