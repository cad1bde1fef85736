//! The bridge library of slam-common's `"gtsam"` backend: GTSAM 4.3 (the `gtsam` wheel from
//! PyPI, which ships GTSAM compiled into its Python extension and no C++ headers) driven
//! through CPython embedded with pyo3. slam-common loads this library at run time, and only
//! when a configuration says `backend.name = "gtsam"`, so plugins themselves never link
//! libpython. The interface (an abi_stable root module with three functions and a byte
//! protocol) is in the `vinebench-gtsam-ffi` crate; the graph logic is the Python module
//! `bridge.py` beside this file, compiled into the library: GTSAM's ISAM2 (Kaess et al.,
//! "iSAM2: Incremental smoothing and mapping using the Bayes tree", IJRR 31(2), 2012) and
//! its CombinedImuFactor (Forster et al., "On-Manifold Preintegration for Real-Time
//! Visual-Inertial Odometry", IEEE T-RO 33(1), 2017).
//!
//! Where Python finds GTSAM: the `site-packages` of the virtual environment in
//! `VINEBENCH_GTSAM_VENV`, else of `<workspace>/target/gtsam-venv` (made by
//! `scripts/setup.sh` with Debian's `/usr/bin/python3`, so its packages match the
//! libpython3.11 this library links), put first on `sys.path`.
//!
//! The interpreter is started by `vinebench-python-embed` (shared with the Python plugin
//! bridge). Unsafe code (denied in the rest of the workspace) is the abi_stable export of
//! the root module, explained where it is.

use std::collections::BTreeMap;
use std::ffi::CString;
use std::panic::{AssertUnwindSafe, catch_unwind};
use std::path::PathBuf;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Mutex, OnceLock};

use abi_stable::std_types::{RResult, RSlice, RString, RVec};
use pyo3::prelude::*;
use pyo3::types::PyBytes;

/// The Python half, compiled in.
const BRIDGE_PY: &str = include_str!("bridge.py");

/// The virtual environment holding `gtsam` when `VINEBENCH_GTSAM_VENV` is not set.
const DEFAULT_VENV: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/../../target/gtsam-venv");

mod export {
    // The root module's header under its own symbol (see `gtsam_ffi::EXPORT_NAME`), built as
    // abi_stable's `#[export_root_module]` builds it: an exported static (an unsafe
    // attribute) made by `LibHeader::from_constructor`, unsafe because the constructor must
    // return the module type named, which `root` does. abi_stable checks the module's
    // layout against the loader's when it is loaded.
    #![allow(unsafe_code)]

    use abi_stable::library::{
        __call_root_module_loader, CheckTypeLayout, LibHeader, RootModuleResult,
    };
    use abi_stable::prefix_type::PrefixTypeTrait;
    use gtsam_ffi::{Bridge, BridgeRef};

    fn root() -> BridgeRef {
        Bridge {
            open: super::open,
            call: super::call,
            close: super::close,
        }
        .leak_into_prefix()
    }

    extern "C" fn construct() -> RootModuleResult {
        __call_root_module_loader(root)
    }

    /// Looked up by `gtsam_ffi::load`.
    #[unsafe(export_name = "vinebench_gtsam_bridge_root")]
    pub static VINEBENCH_GTSAM_BRIDGE_ROOT: LibHeader =
        // SAFETY: `construct` returns a `BridgeRef`, the type named here.
        unsafe { LibHeader::from_constructor::<BridgeRef>(construct, CheckTypeLayout::Yes) };
}

/// Graphs by handle. Locked only while the GIL is held, and never across a Python call.
static GRAPHS: Mutex<BTreeMap<u64, Py<PyAny>>> = Mutex::new(BTreeMap::new());
static NEXT_HANDLE: AtomicU64 = AtomicU64::new(1);
/// `bridge.Graph`, or why Python or GTSAM could not be started (then for good).
static GRAPH_CLASS: OnceLock<Result<Py<PyAny>, String>> = OnceLock::new();

/// Runs `f`, turning a panic into an error: nothing may unwind across `extern "C"`.
fn guarded<T>(f: impl FnOnce() -> Result<T, String>) -> RResult<T, RString> {
    match catch_unwind(AssertUnwindSafe(f)) {
        Ok(Ok(v)) => RResult::ROk(v),
        Ok(Err(e)) => RResult::RErr(e.into()),
        Err(panic) => {
            let what = panic
                .downcast_ref::<&str>()
                .map(|s| (*s).to_owned())
                .or_else(|| panic.downcast_ref::<String>().cloned())
                .unwrap_or_default();
            RResult::RErr(format!("GTSAM bridge panicked: {what}").into())
        }
    }
}

extern "C" fn open(config: RSlice<'_, u8>) -> RResult<u64, RString> {
    guarded(|| {
        let class = graph_class()?;
        Python::attach(|py| {
            let graph = class
                .call1(py, (PyBytes::new(py, config.as_slice()),))
                .map_err(|e| python_error(py, &e))?;
            let handle = NEXT_HANDLE.fetch_add(1, Ordering::Relaxed);
            graphs().insert(handle, graph);
            Ok(handle)
        })
    })
}

extern "C" fn call(handle: u64, request: RSlice<'_, u8>) -> RResult<RVec<u8>, RString> {
    guarded(|| {
        graph_class()?;
        Python::attach(|py| {
            let graph = graphs()
                .get(&handle)
                .map(|g| g.clone_ref(py))
                .ok_or_else(|| format!("no GTSAM graph with handle {handle}"))?;
            let reply = graph
                .call_method1(py, "handle", (PyBytes::new(py, request.as_slice()),))
                .map_err(|e| python_error(py, &e))?;
            let bytes = reply
                .bind(py)
                .cast::<PyBytes>()
                .map_err(|e| format!("GTSAM bridge replied with {e}"))?;
            Ok(RVec::from_slice(bytes.as_bytes()))
        })
    })
}

extern "C" fn close(handle: u64) {
    let _ = guarded(|| {
        if GRAPH_CLASS.get().is_some_and(Result::is_ok) {
            Python::attach(|py| drop(graphs().remove(&handle).map(|g| g.into_bound(py))));
        }
        Ok(())
    });
}

fn graphs() -> std::sync::MutexGuard<'static, BTreeMap<u64, Py<PyAny>>> {
    // A panic while holding the lock cannot leave the map inconsistent (single inserts and
    // removes), so a poisoned lock is used as it is.
    GRAPHS.lock().unwrap_or_else(|p| p.into_inner())
}

fn graph_class() -> Result<&'static Py<PyAny>, String> {
    GRAPH_CLASS
        .get_or_init(|| {
            python_embed::start().map_err(|e| format!("GTSAM bridge: {e}"))?;
            Python::attach(load_bridge)
        })
        .as_ref()
        .map_err(Clone::clone)
}

fn venv() -> PathBuf {
    std::env::var_os("VINEBENCH_GTSAM_VENV")
        .map(PathBuf::from)
        .unwrap_or_else(|| PathBuf::from(DEFAULT_VENV))
}

const SETUP_HINT: &str = "run `bash scripts/setup.sh` (or point VINEBENCH_GTSAM_VENV at a venv of /usr/bin/python3 with tests/gtsam/requirements.txt installed)";

/// Puts the venv's site-packages first on `sys.path`, imports gtsam, and compiles
/// `bridge.py`; its `Graph` class.
fn load_bridge(py: Python<'_>) -> Result<Py<PyAny>, String> {
    let err = |e: PyErr| python_error(py, &e);
    let venv = venv();
    python_embed::use_venv(py, &venv, SETUP_HINT).map_err(|e| format!("GTSAM backend: {e}"))?;
    let site = python_embed::site_packages(py, &venv)?;
    if let Err(e) = py.import("gtsam") {
        return Err(format!(
            "GTSAM backend: cannot import the gtsam Python package from {} ({}): {SETUP_HINT}",
            site.display(),
            python_error(py, &e)
        ));
    }
    let code = CString::new(BRIDGE_PY).map_err(|e| e.to_string())?;
    let module = PyModule::from_code(
        py,
        &code,
        c"vinebench_gtsam_bridge.py",
        c"vinebench_gtsam_bridge",
    )
    .map_err(err)?;
    Ok(module.getattr("Graph").map_err(err)?.unbind())
}

/// A Python exception as `Type: message`.
fn python_error(py: Python<'_>, e: &PyErr) -> String {
    python_embed::error_line(py, e)
}
