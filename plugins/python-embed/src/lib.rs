//! CPython embedded in a plugin library, started once per process: what the GTSAM backend's
//! bridge (`plugins/gtsam-backend`) and the Python plugin bridge (`plugins/python-bridge`)
//! both need before they import anything.
//!
//! - [`start`] makes libpython's symbols global (extension modules in wheels expect them,
//!   see [`make_libpython_global`]), initialises the interpreter and puts a virtual
//!   environment's `site-packages` first on `sys.path`. The environment must be made from
//!   the interpreter this library links (Debian's `/usr/bin/python3`, pinned by
//!   `PYO3_PYTHON` in `.cargo/config.toml`): packages are built for one Python version.
//! - [`error_line`] turns a Python exception into the one line a run fails with.
//!
//! Unsafe code (denied in the rest of the workspace) is one `dladdr` and one `dlopen`,
//! each explained where it is.

use std::ffi::CStr;
use std::path::{Path, PathBuf};

use pyo3::prelude::*;
use pyo3::types::PyList;

/// Python's `major.minor`, as the interpreter reports it.
pub fn version(py: Python<'_>) -> Result<(u32, u32), String> {
    let sys = py.import("sys").map_err(|e| error_line(py, &e))?;
    sys.getattr("version_info")
        .and_then(|v| Ok((v.get_item(0)?.extract()?, v.get_item(1)?.extract()?)))
        .map_err(|e| error_line(py, &e))
}

/// The `site-packages` folder of the virtual environment `venv` for this interpreter.
pub fn site_packages(py: Python<'_>, venv: &Path) -> Result<PathBuf, String> {
    let (major, minor) = version(py)?;
    Ok(venv.join(format!("lib/python{major}.{minor}/site-packages")))
}

/// Starts the interpreter if it is not running (idempotent) with libpython's symbols global.
pub fn start() -> Result<(), String> {
    static STARTED: std::sync::OnceLock<Result<(), String>> = std::sync::OnceLock::new();
    STARTED
        .get_or_init(|| {
            make_libpython_global()?;
            Python::initialize();
            Python::attach(|py| -> Result<(), String> {
                // Embedded, `sys.argv` is missing; some packages read it at import.
                let sys = py.import("sys").map_err(|e| error_line(py, &e))?;
                if !sys.hasattr("argv").map_err(|e| error_line(py, &e))? {
                    let argv = PyList::new(py, [""]).map_err(|e| error_line(py, &e))?;
                    sys.setattr("argv", argv).map_err(|e| error_line(py, &e))?;
                }
                Ok(())
            })
        })
        .clone()
}

/// Puts `folder` first on `sys.path` (once: a folder already there is left where it is).
pub fn prepend_path(py: Python<'_>, folder: &Path) -> Result<(), String> {
    let err = |e: PyErr| error_line(py, &e);
    let sys = py.import("sys").map_err(err)?;
    let path = sys.getattr("path").map_err(err)?;
    let path = path.cast::<PyList>().map_err(|e| e.to_string())?;
    let folder = folder.to_string_lossy();
    if !path.contains(folder.as_ref()).map_err(err)? {
        path.insert(0, folder.as_ref()).map_err(err)?;
    }
    Ok(())
}

/// Puts the virtual environment's `site-packages` first on `sys.path`; an error naming the
/// environment and `hint` (how to make it) if it has none for this Python.
pub fn use_venv(py: Python<'_>, venv: &Path, hint: &str) -> Result<(), String> {
    let site = site_packages(py, venv)?;
    if !site.is_dir() {
        let (major, minor) = version(py)?;
        return Err(format!(
            "no Python {major}.{minor} environment at {}: {hint}",
            venv.display()
        ));
    }
    prepend_path(py, &site)
}

/// A Python exception as one line, `Type: message` (its first line when the message has
/// several).
pub fn error_line(py: Python<'_>, e: &PyErr) -> String {
    let kind = e
        .get_type(py)
        .name()
        .map(|n| n.to_string())
        .unwrap_or_else(|_| "Exception".into());
    let message = e.value(py).to_string();
    let message = message.trim();
    match message.lines().next() {
        Some(first) if !first.trim().is_empty() => format!("{kind}: {}", first.trim()),
        _ => kind,
    }
}

/// [`error_line`], after printing the exception's whole traceback to standard error (a run's
/// `worker.log`), where its author looks for the line that raised it.
pub fn logged_error_line(py: Python<'_>, e: &PyErr) -> String {
    e.clone_ref(py).display(py);
    error_line(py, e)
}

/// Extension modules in wheels are not linked against libpython: they expect the
/// interpreter's symbols to be global already, as they are in the `python3` executable.
/// Here libpython came in as a plugin library's dependency, whose symbols `dlopen` keeps
/// local; reopening it with `RTLD_NOLOAD | RTLD_GLOBAL` (found through the address of one of
/// its functions) makes them global without loading anything new.
fn make_libpython_global() -> Result<(), String> {
    let symbol = pyo3::ffi::Py_IsInitialized as *const libc::c_void;
    let mut info = std::mem::MaybeUninit::<libc::Dl_info>::zeroed();
    // SAFETY: dladdr only reads the address and fills `info`, which is valid for writes;
    // `dli_fname` points into the loader's own data, valid while libpython stays loaded
    // (it is never unloaded: the calling library depends on it).
    #[allow(unsafe_code)]
    let path = unsafe {
        if libc::dladdr(symbol, info.as_mut_ptr()) == 0
            || info.assume_init_ref().dli_fname.is_null()
        {
            return Err("cannot find which library holds libpython".into());
        }
        CStr::from_ptr(info.assume_init_ref().dli_fname).to_owned()
    };
    // SAFETY: RTLD_NOLOAD only changes the flags of a library already loaded (no
    // initialisers run); the handle is deliberately kept, so it stays global.
    #[allow(unsafe_code)]
    let handle = unsafe {
        libc::dlopen(
            path.as_ptr(),
            libc::RTLD_LAZY | libc::RTLD_NOLOAD | libc::RTLD_GLOBAL,
        )
    };
    if handle.is_null() {
        return Err(format!("cannot make {} global", path.to_string_lossy()));
    }
    Ok(())
}
