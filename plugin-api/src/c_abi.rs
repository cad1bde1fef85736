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

use crate::messages::{
    Gnss, Imu, LaserScan, LidarPoint, PointCloud, Pose, RgbdFrame, WheelOdometry,
};
use crate::rig::Rig;
use crate::system::{
    InitialGuess, MapStart, OccupancyGrid, PluginError, PoseStatus, Requirements, SavedMap,
    SlamOutput,
};

/// The header's `VB_ABI_VERSION`: the major version, the same for every table the host
/// accepts.
pub const ABI_VERSION: u32 = 1;
/// The header's `VB_ABI_REVISION`: how many rounds of appended fields it has
/// (docs/plugin-contract.md, "Versions").
pub const ABI_REVISION: u32 = 5;
/// The symbol a C plugin exports.
pub const SYMBOL: &[u8] = b"vinebench_plugin_v1\0";

const NO_POSE: i32 = 0;
const POSE: i32 = 1;
/// Revision 4: a pose, the system still searching where it is in its map.
const POSE_SEARCHING: i32 = 2;

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

/// The header's `vb_param`.
#[repr(C)]
struct ParamC {
    key: *const c_char,
    value: f64,
}

/// The header's `vb_sensor`.
#[repr(C)]
struct SensorC {
    name: *const c_char,
    kind: *const c_char,
    rate_hz: f64,
    base_from_sensor_xyz: [f64; 3],
    base_from_sensor_xyzw: [f64; 4],
    intrinsics: *const ParamC,
    n_intrinsics: usize,
    noise: *const ParamC,
    n_noise: usize,
}

/// The header's `vb_rig`.
#[repr(C)]
struct RigC {
    sensors: *const SensorC,
    n_sensors: usize,
}

/// The header's `vb_create_info`.
#[repr(C)]
struct CreateInfoC {
    struct_size: u32,
    abi_revision: u32,
    config_toml: *const c_char,
    rig_toml: *const c_char,
    rig: *const RigC,
    // Revision 4.
    map: *const u8,
    map_len: usize,
    map_format: *const c_char,
    map_format_version: u32,
    initial_guess: *const InitialGuess,
}

#[repr(C)]
struct OutputC {
    trajectory: *const Pose,
    n_trajectory: usize,
    map_xyz: *const f32,
    n_map_points: usize,
    grid: *const GridC,
    events_toml: *const c_char,
    // Revision 4.
    saved_map: *const u8,
    saved_map_len: usize,
    saved_map_format: *const c_char,
    saved_map_version: u32,
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
    // Revision 2.
    requirements_for: Option<unsafe extern "C" fn(*const c_char) -> *const c_char>,
    create_with: Option<unsafe extern "C" fn(*const CreateInfoC) -> *mut c_void>,
    // Revision 5.
    on_gnss: Callback<Gnss>,
}

/// `sizeof(vb_plugin)` of revision 1: the smallest table the host accepts.
const TABLE_SIZE_REVISION_1: usize = std::mem::offset_of!(Table, requirements_for);

/// A loaded C plugin's table: the host's own copy of the part the plugin's `struct_size`
/// covers (fields past it are NULL), whose functions live in the library, which the loader
/// keeps loaded for the life of the process.
#[derive(Clone, Copy)]
pub struct CPlugin {
    table: &'static Table,
}

/// The host's copy of a plugin's table of `size` bytes at `table`: the fields it has, and
/// NULL for those appended after the plugin was built.
///
/// # Safety
/// `table` points to at least `min(size, size_of::<Table>())` readable bytes laid out as the
/// header's `vb_plugin`.
unsafe fn copy_table(table: *const Table, size: usize) -> &'static Table {
    // SAFETY: every field of `Table` is an integer, a pointer or an `Option` of a function
    // pointer, for each of which all-zero bytes are valid (0, NULL, None).
    let mut copy: Table = unsafe { std::mem::zeroed() };
    let n = size.min(size_of::<Table>());
    // SAFETY: the caller guarantees `n` readable bytes at `table`; `copy` has room for
    // `size_of::<Table>() >= n` bytes, and the two do not overlap.
    unsafe {
        std::ptr::copy_nonoverlapping(table.cast::<u8>(), (&raw mut copy).cast::<u8>(), n);
    }
    // One per library loaded, for the life of the process, as the library itself.
    Box::leak(Box::new(copy))
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
        if (size as usize) < TABLE_SIZE_REVISION_1 {
            return Err(format!(
                "its vb_plugin is {size} bytes (struct_size), smaller than revision 1's \
                 {TABLE_SIZE_REVISION_1}: set struct_size = sizeof(vb_plugin)"
            ));
        }
        // SAFETY: checked non-null and of this version; the plugin's `struct_size` says how
        // many bytes its table has, at least revision 1's.
        let table = unsafe { copy_table(table, size as usize) };
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
            (
                table.create.is_some() || table.create_with.is_some(),
                "create (or create_with)",
            ),
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

    /// The requirements for this parameter table: the plugin's `requirements_for` where its
    /// table has one, else `requirements` (what it said when loaded).
    pub fn requirements_for(
        &self,
        config_toml: &str,
        requirements: &Requirements,
    ) -> Result<Requirements, PluginError> {
        let Some(ask) = self.table.requirements_for else {
            return Ok(requirements.clone());
        };
        let config = CString::new(config_toml)
            .map_err(|_| PluginError("the parameter table contains a NUL byte".into()))?;
        // SAFETY: the string is NUL-terminated and lives through the call.
        let answer = unsafe { ask(config.as_ptr()) };
        if answer.is_null() {
            return Err(PluginError(format!(
                "requirements failed: {}",
                self.error(std::ptr::null_mut(), "requirements_for")
            )));
        }
        // SAFETY: non-null, NUL-terminated and valid until the plugin's next call.
        let text = unsafe { text(answer, "requirements_for") }.map_err(PluginError)?;
        toml::from_str(&text)
            .map_err(|e| PluginError(format!("unreadable requirements: {}", e.message())))
    }

    /// Creates the system with its parameters and the rig (`create_with` where the table
    /// has it, with the rig typed; else `create`), in localisation mode from `start`'s map
    /// where given (revision 4: through `create_with` only).
    pub fn create(
        &self,
        config_toml: &str,
        rig: &Rig,
        start: Option<&MapStart<'_>>,
    ) -> Result<CInstance, PluginError> {
        let nul = |what: &str| PluginError(format!("the {what} contains a NUL byte"));
        let config = CString::new(config_toml).map_err(|_| nul("parameter table"))?;
        let rig_toml = CString::new(rig.to_toml()).map_err(|_| nul("rig"))?;
        if start.is_some() && self.table.create_with.is_none() {
            return Err(PluginError(
                "localisation needs create_with (revision 4), which this plugin's table lacks"
                    .into(),
            ));
        }
        let format = start
            .map(|s| CString::new(s.format).map_err(|_| nul("map format")))
            .transpose()?;
        let guess = start.and_then(|s| s.initial_guess);
        let this = match (self.table.create_with, self.table.create) {
            (Some(create_with), _) => {
                let typed = TypedRig::new(rig).map_err(|what| nul(&what))?;
                let info = CreateInfoC {
                    struct_size: size_of::<CreateInfoC>() as u32,
                    abi_revision: ABI_REVISION,
                    config_toml: config.as_ptr(),
                    rig_toml: rig_toml.as_ptr(),
                    rig: &typed.rig,
                    // A map of no bytes is still a map: never NULL in localisation mode.
                    map: start.map_or(std::ptr::null(), |s| {
                        if s.map.is_empty() {
                            std::ptr::NonNull::<u8>::dangling().as_ptr().cast_const()
                        } else {
                            s.map.as_ptr()
                        }
                    }),
                    map_len: start.map_or(0, |s| s.map.len()),
                    map_format: format.as_ref().map_or(std::ptr::null(), |f| f.as_ptr()),
                    map_format_version: start.map_or(0, |s| s.format_version),
                    initial_guess: guess.as_ref().map_or(std::ptr::null(), |g| g as *const _),
                };
                // SAFETY: `info` and everything it points to (`typed`, the strings) live
                // through the call.
                unsafe { create_with(&info) }
            }
            // SAFETY: both strings are NUL-terminated and live through the call.
            (None, Some(create)) => unsafe { create(config.as_ptr(), rig_toml.as_ptr()) },
            (None, None) => unreachable!("checked at load: create or create_with"),
        };
        if this.is_null() {
            return Err(PluginError(self.error(std::ptr::null_mut(), "create")));
        }
        Ok(CInstance {
            table: self.table,
            this,
            status: PoseStatus::Localized,
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

/// The header's typed `vb_rig` of a [`Rig`], with the storage its pointers point into.
struct TypedRig {
    rig: RigC,
    _sensors: Vec<SensorC>,
    _params: Vec<Vec<ParamC>>,
    /// The strings, owned through raw pointers (`CString::into_raw`), so that moving this
    /// value never invalidates the pointers the plugin reads (Miri's Stacked Borrows: a
    /// `CString` moved after its `as_ptr` was taken invalidates it); freed on drop.
    strings: Vec<*mut c_char>,
}

impl Drop for TypedRig {
    fn drop(&mut self) {
        for &p in &self.strings {
            // SAFETY: each came from `CString::into_raw` and is freed once, here.
            drop(unsafe { CString::from_raw(p) });
        }
    }
}

impl TypedRig {
    /// `Err` names what holds a NUL byte.
    fn new(rig: &Rig) -> Result<Self, String> {
        // Owned from the start, so that an error part-way frees what was made.
        let mut typed = Self {
            rig: RigC {
                sensors: std::ptr::null(),
                n_sensors: 0,
            },
            _sensors: Vec::new(),
            _params: Vec::new(),
            strings: Vec::new(),
        };
        let strings = &mut typed.strings;
        let mut keep = |s: &str, what: &str| -> Result<*const c_char, String> {
            let c = CString::new(s).map_err(|_| format!("rig's {what} {s:?}"))?;
            let p = c.into_raw();
            strings.push(p);
            Ok(p.cast_const())
        };
        let mut params = Vec::new();
        let mut sensors = Vec::with_capacity(rig.sensors.len());
        for s in &rig.sensors {
            let mut table = |m: &std::collections::BTreeMap<String, f64>| {
                m.iter()
                    .map(|(k, v)| {
                        Ok(ParamC {
                            key: keep(k, "key")?,
                            value: *v,
                        })
                    })
                    .collect::<Result<Vec<_>, String>>()
            };
            let intrinsics = table(&s.intrinsics)?;
            let noise = table(&s.noise)?;
            sensors.push(SensorC {
                name: keep(&s.name, "sensor name")?,
                kind: keep(s.kind.name(), "sensor kind")?,
                rate_hz: s.rate_hz,
                base_from_sensor_xyz: s.base_from_sensor_xyz,
                base_from_sensor_xyzw: s.base_from_sensor_xyzw,
                intrinsics: intrinsics.as_ptr(),
                n_intrinsics: intrinsics.len(),
                noise: noise.as_ptr(),
                n_noise: noise.len(),
            });
            // The vectors' heap buffers do not move when the vectors do.
            params.push(intrinsics);
            params.push(noise);
        }
        typed.rig = RigC {
            sensors: sensors.as_ptr(),
            n_sensors: sensors.len(),
        };
        typed._sensors = sensors;
        typed._params = params;
        Ok(typed)
    }
}

/// A created C plugin.
pub struct CInstance {
    table: &'static Table,
    this: *mut c_void,
    /// The status of the pose last returned (`VB_POSE` or `VB_POSE_SEARCHING`).
    status: PoseStatus,
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
            POSE => {
                self.status = PoseStatus::Localized;
                Ok(Some(estimate))
            }
            POSE_SEARCHING => {
                self.status = PoseStatus::Searching;
                Ok(Some(estimate))
            }
            _ => Err(self.error(what)),
        }
    }

    /// The status of the pose last returned.
    pub fn status(&self) -> PoseStatus {
        self.status
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

    /// A GNSS epoch (revision 5; a table without `on_gnss` ignores it).
    pub fn on_gnss(&mut self, gnss: &Gnss) -> Result<Option<Pose>, PluginError> {
        self.call(self.table.on_gnss, gnss, "on_gnss")
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
            saved_map: std::ptr::null(),
            saved_map_len: 0,
            saved_map_format: std::ptr::null(),
            saved_map_version: 0,
        };
        // SAFETY: `this` is live and `o` is valid for the call.
        if unsafe { finish(self.this, &mut o) } != 0 {
            return Err(self.error("finish"));
        }
        // SAFETY: the header makes the plugin keep what `o` points to alive, of the lengths
        // it gives, until its next call.
        unsafe { output_from_c(&o) }
    }
}

/// What a C plugin's `finish` returned, copied out of its memory and checked: NULL arrays
/// with non-zero lengths, grids without cells, events that are not UTF-8 TOML of known
/// kinds are errors naming the field.
///
/// # Safety
/// Every non-NULL pointer in `o` points to as many elements as its length says (the header's
/// rule for a plugin's output), valid for the call; strings are NUL-terminated.
unsafe fn output_from_c(o: &OutputC) -> Result<SlamOutput, PluginError> {
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
    } else if o.n_map_points.checked_mul(3).is_none() {
        return Err(bad("n_map_points is impossibly large"));
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
        let valid = g.resolution_m.is_finite()
            && g.resolution_m > 0.0
            && g.origin.iter().all(|v| v.is_finite());
        if !valid {
            return Err(bad(
                "the grid's resolution must be positive and its origin finite",
            ));
        }
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
    let saved_map = if o.saved_map.is_null() {
        None
    } else {
        // SAFETY: NUL-terminated, kept alive by the plugin.
        let format =
            unsafe { text(o.saved_map_format, "saved_map_format") }.map_err(|e| bad(&e))?;
        if format.trim().is_empty() {
            return Err(bad("saved_map_format is empty"));
        }
        // SAFETY: `saved_map_len` bytes, as the header requires.
        let bytes = if o.saved_map_len == 0 {
            Vec::new()
        } else {
            unsafe { std::slice::from_raw_parts(o.saved_map, o.saved_map_len) }.to_vec()
        };
        Some(SavedMap {
            format,
            version: o.saved_map_version,
            bytes,
        })
    };
    Ok(SlamOutput {
        trajectory,
        map,
        grid,
        events,
        saved_map,
    })
}

#[cfg(test)]
mod tests {
    use std::mem::{offset_of, size_of};
    use std::process::Command;

    use super::*;

    /// `_Static_assert`s of every mirror's size and field offsets against the header.
    macro_rules! layout {
        ($out:ident, $c:literal, $rust:ty, [$($field:ident),* $(,)?]) => {{
            $out.push_str(&format!(
                "VB_ASSERT(sizeof({}) == {}, \"sizeof({})\");\n",
                $c,
                size_of::<$rust>(),
                $c
            ));
            $(
                $out.push_str(&format!(
                    "VB_ASSERT(offsetof({}, {}) == {}, \"{}.{}\");\n",
                    $c,
                    stringify!($field),
                    offset_of!($rust, $field),
                    $c,
                    stringify!($field)
                ));
            )*
        }};
    }

    /// The assertions for every struct of the header that the host mirrors.
    fn assertions() -> String {
        let mut out = String::new();
        layout!(out, "vb_pose", Pose, [stamp_ns, translation, rotation_xyzw]);
        layout!(
            out,
            "vb_imu",
            Imu,
            [stamp_ns, accel_mps2, gyro_rps, orientation_xyzw]
        );
        layout!(
            out,
            "vb_wheel_odometry",
            WheelOdometry,
            [stamp_ns, linear_mps, angular_rps, odom_from_base]
        );
        layout!(
            out,
            "vb_lidar_point",
            LidarPoint,
            [x, y, z, intensity, time_s, ring]
        );
        layout!(
            out,
            "vb_point_cloud",
            PointCloudC,
            [stamp_ns, sensor, sensor_len, points, n_points]
        );
        layout!(
            out,
            "vb_laser_scan",
            LaserScanC,
            [
                stamp_ns,
                sensor,
                sensor_len,
                angle_min_rad,
                angle_increment_rad,
                time_increment_s,
                range_min_m,
                range_max_m,
                ranges_m,
                n_ranges,
                intensities,
                n_intensities
            ]
        );
        layout!(
            out,
            "vb_rgbd_frame",
            RgbdFrameC,
            [
                stamp_ns, sensor, sensor_len, width, height, rgb, rgb_len, depth_m, depth_len,
                intrinsics
            ]
        );
        layout!(
            out,
            "vb_grid",
            GridC,
            [resolution_m, origin, width, height, cells]
        );
        layout!(
            out,
            "vb_output",
            OutputC,
            [
                trajectory,
                n_trajectory,
                map_xyz,
                n_map_points,
                grid,
                events_toml,
                saved_map,
                saved_map_len,
                saved_map_format,
                saved_map_version
            ]
        );
        layout!(out, "vb_param", ParamC, [key, value]);
        layout!(
            out,
            "vb_sensor",
            SensorC,
            [
                name,
                kind,
                rate_hz,
                base_from_sensor_xyz,
                base_from_sensor_xyzw,
                intrinsics,
                n_intrinsics,
                noise,
                n_noise
            ]
        );
        layout!(out, "vb_rig", RigC, [sensors, n_sensors]);
        layout!(
            out,
            "vb_create_info",
            CreateInfoC,
            [
                struct_size,
                abi_revision,
                config_toml,
                rig_toml,
                rig,
                map,
                map_len,
                map_format,
                map_format_version,
                initial_guess
            ]
        );
        layout!(
            out,
            "vb_initial_guess",
            InitialGuess,
            [map_from_base, sigma_xy_m, sigma_yaw_rad]
        );
        layout!(
            out,
            "vb_plugin",
            Table,
            [
                abi_version,
                struct_size,
                name,
                version,
                requirements_toml,
                create,
                destroy,
                last_error,
                on_imu,
                on_wheel_odometry,
                on_point_cloud,
                on_laser_scan,
                on_rgbd,
                finish,
                requirements_for,
                create_with,
                on_gnss
            ]
        );
        layout!(
            out,
            "vb_gnss",
            Gnss,
            [
                stamp_ns,
                status,
                satellites,
                position_enu_m,
                covariance_enu_m2,
                latitude_deg,
                longitude_deg,
                altitude_m,
                hdop
            ]
        );
        out.push_str(&format!(
            "VB_ASSERT(VB_ABI_VERSION == {ABI_VERSION}, \"VB_ABI_VERSION\");\n\
             VB_ASSERT(VB_ABI_REVISION == {ABI_REVISION}, \"VB_ABI_REVISION\");\n\
             VB_ASSERT(VB_PLUGIN_SIZE_REVISION_1 == {TABLE_SIZE_REVISION_1}, \"revision 1's size\");\n\
             VB_ASSERT(VB_POSE_SEARCHING == {POSE_SEARCHING}, \"VB_POSE_SEARCHING\");\n"
        ));
        out
    }

    /// Compiles `source` with `compiler` and `flags` against the header; the compiler's
    /// complaint if it fails.
    fn compile(compiler: &str, flags: &[&str], name: &str, source: &str) -> Result<(), String> {
        let dir = tempfile_dir();
        let file = dir.join(name);
        std::fs::write(&file, source).expect("write the check's source");
        let include = concat!(env!("CARGO_MANIFEST_DIR"), "/include");
        let output = Command::new(compiler)
            .args(flags)
            .args([
                "-Wall",
                "-Wextra",
                "-Wpedantic",
                "-Werror",
                "-fsyntax-only",
                "-I",
            ])
            .arg(include)
            .arg(&file)
            .output()
            .map_err(|e| format!("cannot run {compiler}: {e} (install gcc and g++)"))?;
        if output.status.success() {
            Ok(())
        } else {
            Err(String::from_utf8_lossy(&output.stderr).into_owned())
        }
    }

    fn tempfile_dir() -> std::path::PathBuf {
        let dir = std::env::temp_dir().join(format!(
            "vinebench-layout-{}-{:?}",
            std::process::id(),
            std::thread::current().id()
        ));
        std::fs::create_dir_all(&dir).expect("temp dir");
        dir
    }

    /// Every C mirror's size and field offsets equal the header's, checked by the C and C++
    /// compilers themselves (`_Static_assert` / `static_assert` of `offsetof` and `sizeof`),
    /// and the header compiles as C11 and C++17 with every warning an error.
    #[test]
    #[cfg_attr(miri, ignore = "runs the C compilers")]
    fn the_mirrors_have_the_header_s_layouts_in_c11_and_cpp17() {
        let checks = assertions();
        assert!(checks.matches("VB_ASSERT").count() > 80, "{checks}");
        let c = format!(
            "#include <stddef.h>\n#include \"vinebench_plugin.h\"\n#define VB_ASSERT _Static_assert\n{checks}"
        );
        compile("cc", &["-std=c11", "-x", "c"], "layout.c", &c).expect("C11");
        let cpp = format!(
            "#include <cstddef>\n#include \"vinebench_plugin.h\"\n#define VB_ASSERT static_assert\n{checks}"
        );
        compile("c++", &["-std=c++17", "-x", "c++"], "layout.cpp", &cpp).expect("C++17");
        // The check can fail: one wrong offset is refused by the compiler.
        let wrong = c.replacen(
            &format!(
                "offsetof(vb_rgbd_frame, rgb) == {}",
                offset_of!(RgbdFrameC, rgb)
            ),
            &format!(
                "offsetof(vb_rgbd_frame, rgb) == {}",
                offset_of!(RgbdFrameC, rgb) + 8
            ),
            1,
        );
        assert_ne!(wrong, c);
        let refused = compile("cc", &["-std=c11", "-x", "c"], "wrong.c", &wrong)
            .expect_err("a wrong offset does not compile");
        assert!(refused.contains("vb_rgbd_frame.rgb"), "{refused}");
    }

    /// The unsafe reads of the C door's host side, checked under Miri
    /// (`MIRIFLAGS=-Zmiri-ignore-leaks cargo +nightly miri test -p vinebench-plugin-api c_abi`,
    /// docs/fuzzing.md; the tables are leaked on purpose, one per library for the process's
    /// life): a plugin's output is copied
    /// out whole and right, NULL arrays with lengths are refused, the typed rig's pointers
    /// read back as the rig, and arbitrary answers never read out of bounds.
    #[test]
    fn the_c_door_reads_what_a_plugin_hands_back_within_its_bounds() {
        let poses = [
            Pose {
                stamp_ns: 5,
                translation: [1.0, 2.0, 3.0],
                rotation_xyzw: [0.0, 0.0, 0.0, 1.0],
            },
            Pose {
                stamp_ns: 6,
                translation: [1.5, 2.0, 3.0],
                rotation_xyzw: [0.0, 0.0, 0.0, 1.0],
            },
        ];
        let map = [0.5f32, 0.25, -1.0];
        let cells = [0i8, 100, -1, 50];
        let grid = GridC {
            resolution_m: 0.1,
            origin: [-1.0, -2.0, 0.0],
            width: 2,
            height: 2,
            cells: cells.as_ptr(),
        };
        let events = c"[[events]]\nstamp_ns = 6\nkind = \"loop_closure_accepted\"\ndetail = \"c\"\nloop_stamps_ns = [6, 5]\n";
        let mut o = OutputC {
            trajectory: poses.as_ptr(),
            n_trajectory: 2,
            map_xyz: map.as_ptr(),
            n_map_points: 1,
            grid: &grid,
            events_toml: events.as_ptr(),
            saved_map: [1u8, 2, 3].as_ptr(),
            saved_map_len: 3,
            saved_map_format: c"keyframes".as_ptr(),
            saved_map_version: 2,
        };
        // SAFETY: every pointer points to as many elements as its length says.
        let out = unsafe { output_from_c(&o) }.expect("a valid output");
        assert_eq!(out.trajectory, poses);
        assert_eq!(
            out.saved_map,
            Some(SavedMap {
                format: "keyframes".into(),
                version: 2,
                bytes: vec![1, 2, 3],
            })
        );
        assert_eq!(out.map, Some(vec![[0.5, 0.25, -1.0]]));
        let g = out.grid.expect("grid");
        assert_eq!((g.width, g.height, g.cells.as_slice()), (2, 2, &cells[..]));
        assert_eq!(out.events.len(), 1);
        assert_eq!(out.events[0].loop_stamps_ns, Some([6, 5]));
        o.saved_map_format = std::ptr::null();
        // SAFETY: as above; the missing format is what is checked.
        let refused = unsafe { output_from_c(&o) }.expect_err("a map without its format");
        assert!(refused.0.contains("saved_map_format is NULL"), "{refused}");
        o.saved_map = std::ptr::null();
        o.trajectory = std::ptr::null();
        // SAFETY: as above; the NULL is what is checked.
        let refused = unsafe { output_from_c(&o) }.expect_err("NULL with a length");
        assert!(refused.0.contains("trajectory is NULL"), "{refused}");

        let rig = Rig {
            sensors: vec![crate::SensorSpec {
                name: "lidar".into(),
                kind: crate::SensorKind::Lidar,
                rate_hz: 10.0,
                base_from_sensor_xyz: [0.1, 0.0, 1.5],
                base_from_sensor_xyzw: [0.0, 0.0, 0.0, 1.0],
                intrinsics: [("rings".to_owned(), 16.0)].into_iter().collect(),
                noise: [("range_sigma_m".to_owned(), 0.03)].into_iter().collect(),
            }],
        };
        let typed = TypedRig::new(&rig).expect("no NUL");
        assert_eq!(typed.rig.n_sensors, 1);
        // SAFETY: the typed rig's pointers point into `typed`, alive here.
        let (name, kind, rings, sigma) = unsafe {
            let s = &*typed.rig.sensors;
            (
                CStr::from_ptr(s.name).to_str().expect("utf-8"),
                CStr::from_ptr(s.kind).to_str().expect("utf-8"),
                (*s.intrinsics).value,
                (*s.noise).value,
            )
        };
        assert_eq!((name, kind, rings, sigma), ("lidar", "lidar", 16.0, 0.03));

        for data in [
            &b""[..],
            &[0xff; 64][..],
            &[1, 3, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0xf0, 0x7f][..],
            b"\x1f\x02[[events]]\nkind = 1",
        ] {
            fuzzing::c_output(data);
            fuzzing::c_answers(data);
        }
    }

    /// A table of revision 1's size loads with its revision-2 fields read as absent, even
    /// where the bytes after it hold something.
    #[test]
    fn a_revision_1_table_reads_as_absent_what_it_lacks() {
        unsafe extern "C" fn never(_: *const c_char) -> *const c_char {
            panic!("a field past struct_size was read")
        }
        // SAFETY: all-zero bytes are a valid Table (see copy_table).
        let mut full: Table = unsafe { std::mem::zeroed() };
        full.abi_version = ABI_VERSION;
        full.struct_size = TABLE_SIZE_REVISION_1 as u32;
        full.requirements_for = Some(never);
        // SAFETY: `full` has size_of::<Table>() readable bytes.
        let copy = unsafe { copy_table(&full, TABLE_SIZE_REVISION_1) };
        assert!(copy.requirements_for.is_none());
        assert!(copy.create_with.is_none());
        let plugin = CPlugin { table: copy };
        let r = Requirements::online(&[crate::SensorKind::Lidar]);
        assert_eq!(plugin.requirements_for("x = 1", &r), Ok(r.clone()));
        // The whole table keeps it.
        // SAFETY: as above.
        let whole = unsafe { copy_table(&full, size_of::<Table>()) };
        assert!(whole.requirements_for.is_some());
    }
}

/// Drives the C door's host side with arbitrary values, as a C plugin could hand them back
/// (`fuzz/`; and the stable replay of its corpus). Not part of the API.
#[doc(hidden)]
pub mod fuzzing {
    use std::cell::RefCell;
    use std::ffi::{c_char, c_void};

    use super::*;

    /// Reads values off the front of the fuzzer's bytes; zeros once they run out.
    struct Bytes<'a>(&'a [u8]);

    impl Bytes<'_> {
        fn take<const N: usize>(&mut self) -> [u8; N] {
            let mut out = [0u8; N];
            let n = N.min(self.0.len());
            out[..n].copy_from_slice(&self.0[..n]);
            self.0 = &self.0[n..];
            out
        }
        fn u8(&mut self) -> u8 {
            self.take::<1>()[0]
        }
        fn f64(&mut self) -> f64 {
            f64::from_le_bytes(self.take())
        }
        fn f32(&mut self) -> f32 {
            f32::from_le_bytes(self.take())
        }
        fn i64(&mut self) -> i64 {
            i64::from_le_bytes(self.take())
        }
        /// A NUL-terminated string of up to `max` arbitrary bytes (UTF-8 or not).
        fn c_string(&mut self, max: usize) -> Vec<u8> {
            let n = (self.u8() as usize).min(max).min(self.0.len());
            let mut s: Vec<u8> = self.0[..n].iter().map(|&b| b.max(1)).collect();
            self.0 = &self.0[n..];
            s.push(0);
            s
        }
    }

    /// `finish`'s output built from `data` (arrays, NULLs with lengths, a grid, events TOML
    /// text) and read as the host reads a C plugin's; it must answer, never panic.
    pub fn c_output(data: &[u8]) {
        let mut b = Bytes(data);
        let flags = b.u8();
        let n_poses = (b.u8() % 16) as usize;
        let poses: Vec<Pose> = (0..n_poses)
            .map(|_| Pose {
                stamp_ns: b.i64(),
                translation: [b.f64(), b.f64(), b.f64()],
                rotation_xyzw: [b.f64(), b.f64(), b.f64(), b.f64()],
            })
            .collect();
        let n_points = (b.u8() % 16) as usize;
        let map: Vec<f32> = (0..3 * n_points).map(|_| b.f32()).collect();
        let (w, h) = ((b.u8() % 8) as u32, (b.u8() % 8) as u32);
        let cells: Vec<i8> = (0..w * h).map(|_| b.u8() as i8).collect();
        let grid = GridC {
            resolution_m: b.f64(),
            origin: [b.f64(), b.f64(), b.f64()],
            width: w,
            height: h,
            cells: if flags & 4 != 0 {
                std::ptr::null()
            } else {
                cells.as_ptr()
            },
        };
        let events = b.c_string(4096);
        let saved: Vec<u8> = (0..b.u8() % 32).map(|_| b.u8()).collect();
        let saved_format = b.c_string(64);
        let o = OutputC {
            trajectory: if flags & 1 != 0 {
                std::ptr::null()
            } else {
                poses.as_ptr()
            },
            n_trajectory: n_poses,
            map_xyz: if flags & 2 != 0 {
                std::ptr::null()
            } else {
                map.as_ptr()
            },
            n_map_points: n_points,
            grid: if flags & 8 != 0 {
                std::ptr::null()
            } else {
                &grid
            },
            events_toml: if flags & 16 != 0 {
                std::ptr::null()
            } else {
                events.as_ptr().cast()
            },
            saved_map: if flags & 32 != 0 {
                std::ptr::null()
            } else {
                saved.as_ptr()
            },
            saved_map_len: saved.len(),
            saved_map_format: if flags & 64 != 0 {
                std::ptr::null()
            } else {
                saved_format.as_ptr().cast()
            },
            saved_map_version: u32::from(flags),
        };
        // SAFETY: every non-NULL pointer points to as many elements as its length says.
        let _ = unsafe { output_from_c(&o) };
    }

    thread_local! {
        static ANSWER: RefCell<(i32, Pose, Vec<u8>, Vec<u8>)> = RefCell::new((
            0,
            Pose { stamp_ns: 0, translation: [0.0; 3], rotation_xyzw: [0.0, 0.0, 0.0, 1.0] },
            vec![0],
            vec![0],
        ));
    }

    unsafe extern "C" fn answer(_: *mut c_void, _: *const Imu, estimate: *mut Pose) -> i32 {
        ANSWER.with(|a| {
            let a = a.borrow();
            // SAFETY: the host passes a valid estimate to fill.
            unsafe { *estimate = a.1 };
            a.0
        })
    }

    unsafe extern "C" fn last_error(_: *mut c_void) -> *const c_char {
        ANSWER.with(|a| a.borrow().2.as_ptr().cast())
    }

    unsafe extern "C" fn requirements_for(_: *const c_char) -> *const c_char {
        ANSWER.with(|a| {
            let a = a.borrow();
            if a.3.len() == 1 {
                std::ptr::null()
            } else {
                a.3.as_ptr().cast()
            }
        })
    }

    /// A message answered with an arbitrary return code, pose and error text, and
    /// requirements answered with arbitrary text (or NULL), as a C plugin could; the host
    /// must turn each into a pose, no pose or an error, never panic.
    pub fn c_answers(data: &[u8]) {
        let mut b = Bytes(data);
        let code = i32::from_le_bytes(b.take());
        let pose = Pose {
            stamp_ns: b.i64(),
            translation: [b.f64(), b.f64(), b.f64()],
            rotation_xyzw: [b.f64(), b.f64(), b.f64(), b.f64()],
        };
        let error = b.c_string(512);
        let requirements = b.c_string(2048);
        ANSWER.with(|a| *a.borrow_mut() = (code, pose, error, requirements));
        thread_local! {
            // One per thread, for the thread's life, as a loaded library's table is.
            static TABLE: &'static Table = {
                // SAFETY: all-zero bytes are a valid Table (see copy_table).
                let mut table: Table = unsafe { std::mem::zeroed() };
                table.last_error = Some(last_error);
                table.on_imu = Some(answer);
                table.requirements_for = Some(requirements_for);
                Box::leak(Box::new(table))
            };
        }
        let table: &'static Table = TABLE.with(|t| *t);
        let plugin = CPlugin { table };
        let _ = plugin.requirements_for("x = 1", &Requirements::default());
        let mut instance = CInstance {
            table,
            // Never dereferenced by these callbacks; `destroy` is absent.
            this: std::ptr::NonNull::<u8>::dangling().as_ptr().cast(),
            status: PoseStatus::Localized,
        };
        let imu = Imu {
            stamp_ns: 1,
            accel_mps2: [0.0, 0.0, 9.81],
            gyro_rps: [0.0; 3],
            orientation_xyzw: [0.0; 4],
        };
        if let Ok(Some(p)) = instance.on_imu(&imu) {
            // What the worker then checks before recording it.
            let _ = p.isometry();
            let _ = instance.status();
        }
    }
}
