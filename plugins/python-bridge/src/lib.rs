//! `python-bridge`: a vinebench plugin that hosts a SLAM system written in Python.
//!
//! The bench file names the class and where it lives; every other parameter is the class's
//! own:
//!
//! ```toml
//! [[plugins]]
//! name = "python-bridge"
//! label = "kiss-icp"
//! [plugins.params]
//! module = "kiss_icp_adapter"          # imported with importlib
//! class = "KissIcp"
//! path = "../plugins/python-bridge/adapters"  # put first on sys.path (a string or a list)
//! venv = "../target/kiss-icp-venv"     # its site-packages first on sys.path
//! max_range = 100.0                    # ... the class's own parameters
//! ```
//!
//! Relative `path` and `venv` are relative to the bench file's folder (as the bench file's
//! own paths are; the runner hands it over in `VINEBENCH_BENCH_DIR`), else to the current
//! folder. The venv must be made from the Python this library links (Debian's
//! `/usr/bin/python3`, 3.11: `PYO3_PYTHON` in `.cargo/config.toml`) and hold numpy.
//!
//! The class sees a Rust plugin's lifecycle (`python/vinebench_plugin.py` is the contract
//! with an example): `requirements(params)` (a static method: sensor kinds and mode),
//! `__init__(params, rig)`, one method per sensor kind (`on_imu`, `on_wheel_odometry`,
//! `on_point_cloud`, `on_laser_scan`, `on_rgbd`; absent ones are not called), each
//! returning `None` or `(stamp_ns, map_from_base 4x4)`, and `finish()` returning a dict of
//! `trajectory`, `events` and `map`. Messages are objects of `src/bridge.py` whose arrays
//! are numpy views of the host's buffers (no copies): valid during the call only. A class
//! that keeps one past the call fails the run with a line saying so, instead of reading
//! freed memory later.
//!
//! A Python exception fails the run with the exception's `Type: message`; anything else
//! (a segfault in an extension module, a hang, memory) ends the worker process and so this
//! run only, as for any plugin.
//!
//! Unsafe code (denied in the rest of the workspace) is the buffer protocol of `Lent`, which
//! shows the host's message buffers to numpy read-only, explained where it is.

use std::ffi::CString;
use std::path::{Path, PathBuf};

use nalgebra::{Isometry3, Matrix3, Rotation3, Translation3, UnitQuaternion, Vector3};
use plugin_api::{
    Event, EventKind, Gnss, Imu, LaserScan, MapStart, Mode, OccupancyGrid, PluginError, PointCloud,
    Pose, PoseStatus, Requirements, RgbdFrame, Rig, SavedMap, SensorKind, SlamOutput, SlamSystem,
    WheelOdometry, export_plugin,
};
use pyo3::prelude::*;
use pyo3::types::{PyBytes, PyTuple};

/// The Python half, compiled in.
const BRIDGE_PY: &str = include_str!("bridge.py");

/// The parameters the bridge reads; the rest are the class's.
const BRIDGE_KEYS: [&str; 4] = ["module", "class", "path", "venv"];

/// Where the hosted class comes from.
#[derive(Debug, Clone, PartialEq)]
struct Spec {
    module: String,
    class: String,
    paths: Vec<PathBuf>,
    venv: Option<PathBuf>,
    /// The class's own parameters, as TOML.
    params_toml: String,
}

fn base_dir() -> PathBuf {
    std::env::var_os("VINEBENCH_BENCH_DIR")
        .map(PathBuf::from)
        .or_else(|| std::env::current_dir().ok())
        .unwrap_or_default()
}

impl Spec {
    fn parse(config_toml: &str, base: &Path) -> Result<Self, PluginError> {
        let mut table: toml::Table = toml::from_str(config_toml)
            .map_err(|e| PluginError(format!("python-bridge: parameters: {}", e.message())))?;
        let mut text = |key: &str| -> Result<Option<String>, PluginError> {
            match table.remove(key) {
                None => Ok(None),
                Some(toml::Value::String(s)) => Ok(Some(s)),
                Some(other) => Err(PluginError(format!(
                    "python-bridge: `{key}` must be a string, not {}",
                    other.type_str()
                ))),
            }
        };
        let required = |v: Option<String>, key: &str| {
            v.ok_or_else(|| {
                PluginError(format!(
                    "python-bridge: parameter `{key}` is missing (the Python class to host: `module` and `class`)"
                ))
            })
        };
        let module = required(text("module")?, "module")?;
        let class = required(text("class")?, "class")?;
        let venv = text("venv")?.map(|v| base.join(v));
        let paths = match table.remove("path") {
            None => Vec::new(),
            Some(toml::Value::String(s)) => vec![base.join(s)],
            Some(toml::Value::Array(items)) => items
                .into_iter()
                .map(|v| match v {
                    toml::Value::String(s) => Ok(base.join(s)),
                    other => Err(PluginError(format!(
                        "python-bridge: `path` entries must be strings, not {}",
                        other.type_str()
                    ))),
                })
                .collect::<Result<_, _>>()?,
            Some(other) => {
                return Err(PluginError(format!(
                    "python-bridge: `path` must be a string or a list of strings, not {}",
                    other.type_str()
                )));
            }
        };
        debug_assert!(BRIDGE_KEYS.iter().all(|k| !table.contains_key(*k)));
        let params_toml = toml::to_string(&table).map_err(|e| PluginError(e.to_string()))?;
        Ok(Self {
            module,
            class,
            paths,
            venv,
            params_toml,
        })
    }

    /// The label errors carry: `module.Class`.
    fn name(&self) -> String {
        format!("{}.{}", self.module, self.class)
    }
}

/// Starts Python with the spec's environment; the bridge module and the class.
fn prepare<'py>(
    py: Python<'py>,
    spec: &Spec,
) -> Result<(Bound<'py, PyAny>, Bound<'py, PyAny>), String> {
    if let Some(venv) = &spec.venv {
        python_embed::use_venv(
            py,
            venv,
            "make it with /usr/bin/python3 -m venv and install the system's requirements (scripts/setup.sh does for the shipped adapters)",
        )?;
    }
    for path in spec.paths.iter().rev() {
        if !path.is_dir() {
            return Err(format!("path {} is not a folder", path.display()));
        }
        python_embed::prepend_path(py, path)?;
    }
    let err = |e: PyErr| python_embed::logged_error_line(py, &e);
    let code = CString::new(BRIDGE_PY).map_err(|e| e.to_string())?;
    let shim = PyModule::from_code(py, &code, c"vinebench_bridge.py", c"vinebench_bridge")
        .map_err(err)?
        .into_any();
    configure(&shim).map_err(err)?;
    let class = shim
        .call_method1("load_class", (&spec.module, &spec.class))
        .map_err(err)?;
    Ok((shim, class))
}

/// Hands the bridge module the layouts and registries the Rust side defines, so that
/// `bridge.py` types none of them: the lidar point's numpy fields from `offset_of!`, the
/// sensor and event kinds, the contract's revision.
fn configure(shim: &Bound<'_, PyAny>) -> PyResult<()> {
    use plugin_api::LidarPoint;
    use std::mem::offset_of;
    let fields = vec![
        ("x", "<f4", offset_of!(LidarPoint, x)),
        ("y", "<f4", offset_of!(LidarPoint, y)),
        ("z", "<f4", offset_of!(LidarPoint, z)),
        ("intensity", "<f4", offset_of!(LidarPoint, intensity)),
        ("time_s", "<f4", offset_of!(LidarPoint, time_s)),
        ("ring", "<u2", offset_of!(LidarPoint, ring)),
    ];
    let sensors: Vec<&str> = SensorKind::ALL.iter().map(|k| k.name()).collect();
    let events: Vec<&str> = EventKind::ALL.iter().map(|k| k.name()).collect();
    shim.call_method1(
        "configure",
        (
            fields,
            size_of::<LidarPoint>(),
            sensors,
            events,
            plugin_api::ABI_REVISION,
        ),
    )?;
    Ok(())
}

/// Runs `f` with the GIL, Python started and the hosted class loaded; errors name the
/// class.
fn with_class<T>(
    spec: &Spec,
    f: impl FnOnce(Python<'_>, &Bound<'_, PyAny>, &Bound<'_, PyAny>) -> PyResult<T>,
) -> Result<T, PluginError> {
    let fail = |e: String| PluginError(format!("{}: {e}", spec.name()));
    python_embed::start().map_err(fail)?;
    Python::attach(|py| {
        let (shim, class) = prepare(py, spec).map_err(fail)?;
        f(py, &shim, &class).map_err(|e| fail(python_embed::logged_error_line(py, &e)))
    })
}

/// A hosted Python system.
#[derive(Debug)]
pub struct PythonPlugin {
    name: String,
    shim: Py<PyAny>,
    system: Py<PyAny>,
    /// The status of the pose last returned (revision 4).
    status: PoseStatus,
}

/// A host buffer lent to Python for one call: a read-only buffer-protocol object that
/// numpy wraps without copying (`np.frombuffer`), counting the views it exports so that the
/// bridge knows, when the call returns, whether the plugin kept an array over it.
#[pyclass(frozen, name = "LentBuffer", module = "vinebench_bridge")]
struct Lent {
    ptr: usize,
    len: usize,
    exports: std::sync::atomic::AtomicUsize,
    /// Cleared when the loan ends: a plugin that kept this object itself (not an array)
    /// gets a `BufferError` instead of the host's memory if it asks for a view later.
    alive: std::sync::atomic::AtomicBool,
}

#[pymethods]
impl Lent {
    // SAFETY (the method): `view` is the Py_buffer CPython asks this object to fill.
    #[allow(unsafe_code)]
    unsafe fn __getbuffer__(
        slf: Bound<'_, Self>,
        view: *mut pyo3::ffi::Py_buffer,
        flags: std::ffi::c_int,
    ) -> PyResult<()> {
        if flags & pyo3::ffi::PyBUF_WRITABLE != 0 {
            return Err(pyo3::exceptions::PyBufferError::new_err(
                "the host's message buffers are read-only",
            ));
        }
        let this = slf.get();
        if !this.alive.load(std::sync::atomic::Ordering::Acquire) {
            return Err(pyo3::exceptions::PyBufferError::new_err(
                "a message's buffer was kept past its call (the host's buffers are lent for the call only)",
            ));
        }
        // SAFETY: PyBuffer_FillInfo fills `view` for `len` bytes at `ptr`, read-only (1), and
        // takes a new reference to the exporter (this object), as the protocol requires.
        // `ptr` points to the host's message, alive for the call this object is lent for
        // (see `Views::release`).
        let filled = unsafe {
            pyo3::ffi::PyBuffer_FillInfo(
                view,
                slf.as_ptr(),
                this.ptr as *mut std::ffi::c_void,
                this.len as pyo3::ffi::Py_ssize_t,
                1,
                flags,
            )
        };
        if filled != 0 {
            return Err(PyErr::fetch(slf.py()));
        }
        this.exports
            .fetch_add(1, std::sync::atomic::Ordering::Relaxed);
        Ok(())
    }

    // SAFETY (the method): called by CPython once per view `__getbuffer__` filled.
    #[allow(unsafe_code)]
    unsafe fn __releasebuffer__(&self, _view: *mut pyo3::ffi::Py_buffer) {
        self.exports
            .fetch_sub(1, std::sync::atomic::Ordering::Relaxed);
    }
}

/// Plain `#[repr(C)]` data the host lends to Python: the element types of its messages.
trait Lendable: Copy {}
impl Lendable for u8 {}
impl Lendable for f32 {}
impl Lendable for plugin_api::LidarPoint {}

/// The buffers lent for one call.
struct Views<'py>(Vec<Bound<'py, Lent>>);

impl<'py> Views<'py> {
    /// Lends the memory of `items` (plain `#[repr(C)]` data: u8, f32, LidarPoint) for this
    /// call. The caller keeps `items` alive until [`Views::release`]. No `&[u8]` is made of
    /// it here (LidarPoint has padding bytes, which Rust may not read as bytes): Python
    /// reads the memory through the buffer, and numpy's dtype skips the padding.
    fn lend<T: Lendable>(&mut self, py: Python<'py>, items: &[T]) -> PyResult<Bound<'py, Lent>> {
        let lent = Bound::new(
            py,
            Lent {
                ptr: items.as_ptr() as usize,
                len: size_of_val(items),
                exports: 0.into(),
                alive: true.into(),
            },
        )?;
        self.0.push(lent.clone());
        Ok(lent)
    }

    /// Whether any buffer still has a view (an array the plugin kept).
    fn exported(&self) -> bool {
        self.0
            .iter()
            .any(|l| l.get().exports.load(std::sync::atomic::Ordering::Relaxed) > 0)
    }

    /// Ends the loan: no buffer gives a view any more, and an error if the plugin still
    /// holds an array over one (it would read freed memory later; the run fails now
    /// instead). Arrays held only by reference cycles are collected first.
    fn release(self, py: Python<'py>, method: &str) -> Result<(), String> {
        for lent in &self.0 {
            lent.get()
                .alive
                .store(false, std::sync::atomic::Ordering::Release);
        }
        if self.exported() {
            if let Ok(gc) = py.import("gc") {
                let _ = gc.call_method0("collect");
            }
        }
        if self.exported() {
            return Err(format!(
                "{method}: kept an array of the message past the call (the host's buffers are lent for the call only: keep a copy, e.g. np.array(frame.rgb))"
            ));
        }
        Ok(())
    }
}

fn pose_from(value: Option<(i64, [f64; 12])>) -> Result<Option<Pose>, String> {
    let Some((stamp_ns, m)) = value else {
        return Ok(None);
    };
    if m.iter().any(|v| !v.is_finite()) {
        return Err(format!("a pose at {stamp_ns} ns is not finite"));
    }
    let r = Matrix3::new(m[0], m[1], m[2], m[4], m[5], m[6], m[8], m[9], m[10]);
    if (r.transpose() * r - Matrix3::identity()).abs().max() > 1e-4 || r.determinant() < 0.0 {
        return Err(format!(
            "the pose at {stamp_ns} ns has a rotation block that is not a rotation"
        ));
    }
    let q = UnitQuaternion::from_rotation_matrix(&Rotation3::from_matrix_unchecked(r));
    let t = Translation3::from(Vector3::new(m[3], m[7], m[11]));
    Ok(Some(Pose::new(stamp_ns, &Isometry3::from_parts(t, q))))
}

impl PythonPlugin {
    /// Calls `method` of the bridge module with the system and `args(py, views)`, lending
    /// the message's buffers for the call; the pose it returns.
    fn call(
        &mut self,
        method: &str,
        args: impl for<'py> FnOnce(Python<'py>, &mut Views<'py>) -> PyResult<Bound<'py, PyTuple>>,
    ) -> Result<Option<Pose>, PluginError> {
        let fail = |e: String| PluginError(format!("{}: {e}", self.name));
        Python::attach(|py| {
            let mut views = Views(Vec::new());
            let result = (|| {
                let rest = args(py, &mut views)?;
                let mut all = vec![self.system.bind(py).clone()];
                all.extend(rest.iter());
                let out = self
                    .shim
                    .bind(py)
                    .call_method1(method, PyTuple::new(py, all)?)?;
                out.extract::<Option<(i64, [f64; 12], String)>>()
            })();
            let released = views.release(py, method);
            let value = result.map_err(|e| fail(python_embed::logged_error_line(py, &e)))?;
            released.map_err(fail)?;
            if let Some((_, _, status)) = &value {
                self.status = PoseStatus::from_name(status).map_err(|e| fail(e.0))?;
            }
            pose_from(value.map(|(stamp, rows, _)| (stamp, rows)))
                .map_err(|e| fail(format!("{method}: {e}")))
        })
    }
}

impl SlamSystem for PythonPlugin {
    const NAME: &'static str = "python-bridge";
    const VERSION: &'static str = env!("CARGO_PKG_VERSION");

    /// Without parameters the bridge cannot know: every sensor. The host asks
    /// [`SlamSystem::requirements_for`].
    fn requirements() -> Requirements {
        Requirements::online(&SensorKind::ALL)
    }

    fn requirements_for(config_toml: &str) -> Result<Requirements, PluginError> {
        let spec = Spec::parse(config_toml, &base_dir())?;
        let (sensors, mode, can_localize): (Vec<String>, String, bool) =
            with_class(&spec, |_, shim, class| {
                shim.call_method1("requirements", (class, &spec.params_toml))?
                    .extract()
            })?;
        let sensors = sensors
            .iter()
            .map(|s| {
                SensorKind::ALL
                    .into_iter()
                    .find(|k| k.name() == s)
                    .ok_or_else(|| PluginError(format!("{}: unknown sensor {s}", spec.name())))
            })
            .collect::<Result<_, _>>()?;
        let mode = if mode == "offline" {
            Mode::Offline
        } else {
            Mode::Online
        };
        Ok(Requirements {
            sensors,
            mode,
            can_localize,
        })
    }

    fn new(config_toml: &str, rig: &Rig) -> Result<Self, PluginError> {
        let spec = Spec::parse(config_toml, &base_dir())?;
        let (shim, system) = with_class(&spec, |_, shim, class| {
            let system = shim.call_method1("create", (class, &spec.params_toml, rig.to_toml()))?;
            Ok((shim.clone().unbind(), system.unbind()))
        })?;
        Ok(Self {
            name: spec.name(),
            shim,
            system,
            status: PoseStatus::Localized,
        })
    }

    fn localize(config_toml: &str, rig: &Rig, start: &MapStart<'_>) -> Result<Self, PluginError> {
        let spec = Spec::parse(config_toml, &base_dir())?;
        let guess = start.initial_guess.map(|g| {
            let m = g
                .map_from_base
                .isometry()
                .unwrap_or_else(Isometry3::identity)
                .to_homogeneous();
            let rows: [f64; 12] = std::array::from_fn(|i| m[(i / 4, i % 4)]);
            (rows, g.sigma_xy_m, g.sigma_yaw_rad)
        });
        let (shim, system) = with_class(&spec, |py, shim, class| {
            let system = shim.call_method1(
                "create_localizing",
                (
                    class,
                    &spec.params_toml,
                    rig.to_toml(),
                    PyBytes::new(py, start.map),
                    start.format,
                    start.format_version,
                    guess,
                ),
            )?;
            Ok((shim.clone().unbind(), system.unbind()))
        })?;
        Ok(Self {
            name: spec.name(),
            shim,
            system,
            status: PoseStatus::Searching,
        })
    }

    fn status(&self) -> PoseStatus {
        self.status
    }

    fn on_imu(&mut self, imu: &Imu) -> Result<Option<Pose>, PluginError> {
        let orientation = imu.orientation().map(|q| {
            let c = q.coords;
            (c.x, c.y, c.z, c.w)
        });
        self.call("imu", |py, _| {
            (
                imu.stamp_ns,
                "imu",
                imu.accel_mps2,
                imu.gyro_rps,
                orientation,
            )
                .into_pyobject(py)
        })
    }

    fn on_gnss(&mut self, g: &Gnss) -> Result<Option<Pose>, PluginError> {
        self.call("gnss", |py, _| {
            (
                g.stamp_ns,
                "gnss",
                g.status.name(),
                g.satellites,
                g.position_enu_m,
                g.covariance_enu_m2,
                (g.latitude_deg, g.longitude_deg, g.altitude_m),
                g.hdop,
            )
                .into_pyobject(py)
        })
    }

    fn on_wheel_odometry(&mut self, odom: &WheelOdometry) -> Result<Option<Pose>, PluginError> {
        let pose = odom
            .odom_from_base
            .isometry()
            .ok_or_else(|| PluginError("wheel odometry pose is not finite".into()))?
            .to_homogeneous();
        let rows: [f64; 12] = std::array::from_fn(|i| pose[(i / 4, i % 4)]);
        self.call("wheel_odometry", |py, _| {
            (
                odom.stamp_ns,
                "wheel_odometry",
                odom.linear_mps,
                odom.angular_rps,
                rows,
            )
                .into_pyobject(py)
        })
    }

    fn on_point_cloud(&mut self, cloud: &PointCloud<'_>) -> Result<Option<Pose>, PluginError> {
        self.call("point_cloud", |py, views| {
            (cloud.stamp_ns, cloud.sensor, views.lend(py, cloud.points)?).into_pyobject(py)
        })
    }

    fn on_laser_scan(&mut self, s: &LaserScan<'_>) -> Result<Option<Pose>, PluginError> {
        self.call("laser_scan", |py, views| {
            (
                s.stamp_ns,
                s.sensor,
                (s.angle_min_rad, s.angle_increment_rad, s.time_increment_s),
                (s.range_min_m, s.range_max_m),
                views.lend(py, s.ranges_m)?,
                views.lend(py, s.intensities)?,
            )
                .into_pyobject(py)
        })
    }

    fn on_rgbd(&mut self, f: &RgbdFrame<'_>) -> Result<Option<Pose>, PluginError> {
        let (w, h) = (f.width as usize, f.height as usize);
        if f.rgb.len() != w * h * 3 || f.depth_m.len() != w * h {
            return Err(PluginError(format!(
                "{}: an RGB-D frame of {w}x{h} with {} colour bytes and {} depths",
                self.name,
                f.rgb.len(),
                f.depth_m.len()
            )));
        }
        self.call("rgbd", |py, views| {
            (
                f.stamp_ns,
                f.sensor,
                f.width,
                f.height,
                views.lend(py, f.rgb)?,
                views.lend(py, f.depth_m)?,
                (
                    f.intrinsics[0],
                    f.intrinsics[1],
                    f.intrinsics[2],
                    f.intrinsics[3],
                ),
            )
                .into_pyobject(py)
        })
    }

    fn finish(&mut self) -> Result<SlamOutput, PluginError> {
        let fail = |e: String| PluginError(format!("{}: {e}", self.name));
        let finished: Finished = Python::attach(|py| {
            let out = self
                .shim
                .bind(py)
                .call_method1("finish", (self.system.bind(py),))?;
            #[allow(clippy::type_complexity)]
            let (t, e, m, g, saved): (
                _,
                _,
                Option<Bound<'_, PyBytes>>,
                Option<Bound<'_, PyTuple>>,
                Option<(String, u32, Bound<'_, PyBytes>)>,
            ) = out.extract()?;
            let grid = g
                .map(|g| {
                    let (resolution, origin, width, height, cells): (
                        f64,
                        (f64, f64, f64),
                        u32,
                        u32,
                        Bound<'_, PyBytes>,
                    ) = g.extract()?;
                    Ok::<_, PyErr>((resolution, origin, width, height, cells.as_bytes().to_vec()))
                })
                .transpose()?;
            let saved = saved.map(|(format, version, bytes)| SavedMap {
                format,
                version,
                bytes: bytes.as_bytes().to_vec(),
            });
            Ok::<_, PyErr>((t, e, m.map(|b| b.as_bytes().to_vec()), grid, saved))
        })
        .map_err(|e| Python::attach(|py| fail(python_embed::logged_error_line(py, &e))))?;
        output_from_python(finished).map_err(|e| fail(format!("finish: {e}")))
    }
}

/// A loop's relative pose as the bridge hands it over: 7 numbers (translation, quaternion)
/// or the 12 of a transform's top three rows.
type Relative = Option<Vec<f64>>;
/// A grid as the bridge hands it over: resolution, origin, width, height, cells.
type Grid = Option<(f64, (f64, f64, f64), u32, u32, Vec<u8>)>;
/// A loop's matched keypoints as the bridge hands them over: little-endian f32 bytes, four
/// a match.
type Matches = Option<Vec<u8>>;
/// What `bridge.py`'s `finish` returns, extracted: trajectory, events, map bytes, grid,
/// saved map.
type Finished = (
    Vec<Option<(i64, [f64; 12])>>,
    Vec<(i64, String, String, Option<(i64, i64)>, Relative, Matches)>,
    Option<Vec<u8>>,
    Grid,
    Option<SavedMap>,
);

/// The Python door's output in the host's types, checked: every pose a finite rotation,
/// every event kind in the registry and every relative pose finite with a unit quaternion,
/// a grid with a positive resolution, a finite origin and width x height cells.
fn output_from_python(
    (trajectory, events, map, grid, saved_map): Finished,
) -> Result<SlamOutput, String> {
    let trajectory = trajectory
        .into_iter()
        .map(|p| {
            pose_from(p).and_then(|p| p.ok_or_else(|| "a trajectory entry is None".to_owned()))
        })
        .collect::<Result<Vec<_>, _>>()?;
    let events = events
        .into_iter()
        .map(|(stamp, kind, detail, stamps, relative, matches)| {
            let kind = EventKind::from_name(&kind).map_err(|e| e.0)?;
            let mut event = match stamps {
                Some((a, b)) if kind.is_loop_closure() => {
                    Event::loop_closure(stamp, kind, [a, b], detail)
                }
                _ => Event::new(stamp, kind, detail),
            };
            if let Some(numbers) = relative {
                event.loop_relative_pose = Some(match numbers.len() {
                    7 => std::array::from_fn(|i| numbers[i]),
                    12 => {
                        let rows: [f64; 12] = std::array::from_fn(|i| numbers[i]);
                        let pose = pose_from(Some((stamp, rows)))?.expect("given");
                        let [x, y, z] = pose.translation;
                        let [qx, qy, qz, qw] = pose.rotation_xyzw;
                        [x, y, z, qx, qy, qz, qw]
                    }
                    n => return Err(format!("the event at {stamp} ns has a loop_relative_pose of {n} numbers")),
                });
                if event.relative_pose().is_none() {
                    return Err(format!(
                        "the event at {stamp} ns has a loop_relative_pose that is not finite with a unit quaternion"
                    ));
                }
            }
            if let Some(bytes) = matches {
                if bytes.len() % 16 != 0 {
                    return Err(format!(
                        "the event at {stamp} ns has loop_matches of {} bytes, not 4 float32 a match",
                        bytes.len()
                    ));
                }
                event.loop_matches = Some(
                    bytes
                        .chunks_exact(16)
                        .map(|c| {
                            std::array::from_fn(|i| {
                                f32::from_le_bytes(c[i * 4..i * 4 + 4].try_into().expect("4 bytes"))
                            })
                        })
                        .collect(),
                );
                if event.matches().is_none() {
                    return Err(format!(
                        "the event at {stamp} ns has loop_matches that are not finite"
                    ));
                }
            }
            Ok(event)
        })
        .collect::<Result<_, String>>()?;
    let map = map.map(|bytes| {
        bytes
            .chunks_exact(12)
            .map(|c| {
                std::array::from_fn(|i| {
                    f32::from_le_bytes(c[i * 4..i * 4 + 4].try_into().expect("4 bytes"))
                })
            })
            .collect()
    });
    let grid = grid
        .map(|(resolution_m, (x, y, yaw), width, height, cells)| {
            let valid = resolution_m.is_finite()
                && resolution_m > 0.0
                && [x, y, yaw].iter().all(|v| v.is_finite());
            if !valid {
                return Err(
                    "the grid's resolution must be positive and its origin finite".to_owned(),
                );
            }
            if cells.len() as u64 != u64::from(width) * u64::from(height) {
                return Err(format!(
                    "the grid is {width}x{height} with {} cells",
                    cells.len()
                ));
            }
            Ok(OccupancyGrid {
                resolution_m,
                origin: [x, y, yaw],
                width,
                height,
                cells: cells.into_iter().map(|c| c as i8).collect(),
            })
        })
        .transpose()?;
    if let Some(saved) = &saved_map
        && saved.format.trim().is_empty()
    {
        return Err("the saved map's format is empty".to_owned());
    }
    Ok(SlamOutput {
        trajectory,
        map,
        grid,
        events,
        saved_map,
    })
}

/// Drives the Python door's host side (what `bridge.py` hands back from a class's `finish`
/// and its message methods) with arbitrary values (`fuzz/`); not part of the API.
#[doc(hidden)]
pub fn fuzz_python_output(data: &[u8]) {
    let mut at = 0usize;
    let mut byte = || {
        let b = data.get(at).copied().unwrap_or(0);
        at += 1;
        b
    };
    let mut f64v = || {
        let mut b = [0u8; 8];
        for x in &mut b {
            *x = byte();
        }
        f64::from_le_bytes(b)
    };
    let poses: Vec<Option<(i64, [f64; 12])>> = (0..f64v().to_bits() % 4)
        .map(|k| (k != 3).then(|| (k as i64, std::array::from_fn(|_| f64v()))))
        .collect();
    for p in &poses {
        let _ = pose_from(*p);
    }
    let kinds = ["loop_closure_accepted", "tracking_lost", "no_such_kind", ""];
    let events = (0..f64v().to_bits() % 4)
        .map(|k| {
            let kind = kinds[(f64v().to_bits() % 4) as usize].to_owned();
            // No relative pose, or 7 numbers, a 3x4 block's 12 or a wrong count.
            let relative = match f64v().to_bits() % 4 {
                0 => None,
                1 => Some(7),
                2 => Some(12),
                _ => Some(3),
            }
            .map(|n| (0..n).map(|_| f64v()).collect());
            // No matches, or some bytes: whole matches of 16, or a ragged end.
            let matches = (f64v().to_bits() % 2 == 1).then(|| {
                (0..(f64v().to_bits() % 40))
                    .map(|_| (f64v().to_bits() & 0xff) as u8)
                    .collect()
            });
            (
                k as i64,
                kind,
                String::new(),
                Some((1, 0)),
                relative,
                matches,
            )
        })
        .collect();
    let map = Some(
        (0..(f64v().to_bits() % 40))
            .map(|_| (f64v().to_bits() & 0xff) as u8)
            .collect(),
    );
    let (w, h) = ((f64v().to_bits() % 5) as u32, (f64v().to_bits() % 5) as u32);
    let cells = (0..(f64v().to_bits() % 30))
        .map(|_| (f64v().to_bits() & 0xff) as u8)
        .collect();
    let grid = Some((f64v(), (f64v(), f64v(), f64v()), w, h, cells));
    let saved = (f64v().to_bits() % 3 != 0).then(|| SavedMap {
        format: ["fmt", "", " "][(f64v().to_bits() % 3) as usize].to_owned(),
        version: (f64v().to_bits() & 0xffff) as u32,
        bytes: vec![(f64v().to_bits() & 0xff) as u8; (f64v().to_bits() % 8) as usize],
    });
    let _ = output_from_python((poses, events, map, grid, saved));
}

export_plugin!(PythonPlugin);

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_bridge_keys_are_taken_and_the_rest_is_the_class_s() {
        let spec = Spec::parse(
            "module = \"m\"\nclass = \"C\"\npath = [\"a\", \"/b\"]\nvenv = \"v\"\nalpha = 2.5\n[section]\nx = 1\n",
            Path::new("/bench"),
        )
        .expect("parses");
        assert_eq!(spec.name(), "m.C");
        assert_eq!(spec.paths, [PathBuf::from("/bench/a"), PathBuf::from("/b")]);
        assert_eq!(spec.venv, Some(PathBuf::from("/bench/v")));
        let rest: toml::Table = toml::from_str(&spec.params_toml).expect("toml");
        assert_eq!(rest.len(), 2, "{rest:?}");
        assert_eq!(rest["alpha"].as_float(), Some(2.5));
        let missing = Spec::parse("module = \"m\"", Path::new("/")).unwrap_err();
        assert!(missing.0.contains("`class` is missing"), "{missing}");
        let wrong = Spec::parse("module = 1\nclass = \"C\"", Path::new("/")).unwrap_err();
        assert!(wrong.0.contains("`module` must be a string"), "{wrong}");
    }

    #[test]
    fn poses_come_from_the_top_three_rows() {
        let iso = Isometry3::new(Vector3::new(1.0, -2.0, 0.5), Vector3::new(0.1, -0.2, 0.3));
        let m = iso.to_homogeneous();
        let rows: [f64; 12] = std::array::from_fn(|i| m[(i / 4, i % 4)]);
        let pose = pose_from(Some((42, rows))).expect("valid").expect("some");
        assert_eq!(pose.stamp_ns, 42);
        let back = pose.isometry().expect("finite");
        assert!((back.translation.vector - iso.translation.vector).norm() < 1e-12);
        assert!(back.rotation.angle_to(&iso.rotation) < 1e-9);
        let mut skew = rows;
        skew[0] = 2.0;
        assert!(pose_from(Some((1, skew))).is_err());
        assert_eq!(pose_from(None), Ok(None));
    }
}
