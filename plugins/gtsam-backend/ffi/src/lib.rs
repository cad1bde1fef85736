//! The interface between slam-common's `"gtsam"` backend and the bridge library
//! (`libvinebench_gtsam.so`, crate `vinebench-gtsam`) that runs GTSAM's Python wrapper in an
//! embedded CPython. It is a crate of its own so that slam-common, and so every plugin,
//! depends on this small interface only: the bridge, which links libpython, is loaded at run
//! time, and only by a plugin whose configuration chooses `backend.name = "gtsam"`.
//!
//! # ABI
//!
//! The bridge exports an abi_stable root module, [`BridgeRef`] (as plugin-api does for
//! plugins), so that loading it checks the abi_stable version, this crate's version
//! (`major.minor` must match) and the layout of [`Bridge`]. It is exported under its own
//! symbol, [`EXPORT_NAME`], not abi_stable's usual one, so that `vinebench plugins` (which
//! tries every library beside the executable) does not take the bridge for a plugin; [`load`]
//! looks it up. A graph is a handle (`u64`)
//! into a table inside the bridge; every operation on it is one [`Bridge::call`] with a
//! request and a reply as bytes, so that the interface stays three functions however the
//! protocol grows. Errors come back as one line of text (a Python exception as
//! `Type: message`); the bridge catches panics.
//!
//! # Protocol
//!
//! All numbers little-endian; `f64` IEEE doubles, `u64` unsigned. A pose is 7 `f64`:
//! `qw qx qy qz tx ty tz` of `world_from_body`; a bias is 6 `f64`: accelerometer xyz, then
//! gyroscope xyz; keys are keyframe indices below 2⁵⁶ (GTSAM's `Symbol` index range).
//!
//! [`Bridge::open`] takes the configuration: `f64` relinearize threshold, `u64`
//! relinearize skip, `f64` wildfire threshold, `u64` max iterations of a full update.
//!
//! A request is an opcode byte and its fields:
//!
//! | request | fields | reply |
//! |---|---|---|
//! | `i` insert | `u8` kind (`x` pose, `v` velocity, `b` bias), `u64` key, value (7, 3 or 6 `f64`) | empty |
//! | `a` add | `u64` factor id, `u8` type and its fields (below) | empty |
//! | `r` remove | `u64` factor id | `u8` 1 if removed, 0 if unknown |
//! | `u` update | `u8` 1 for a full update, 0 for incremental | report and keys (below) |
//! | `e` factor error | `u64` factor id | `u8` 1 if known, `f64` whitened residual norm |
//! | `v` value | `u8` kind, `u64` key | ISAM2's estimate: pose 12 `f64` (rotation matrix row-major, then translation), velocity 3, bias 6 (accelerometer, then gyroscope) |
//! | `c` marginal covariance | `u8` kind (`x` only), `u64` key | ISAM2's `marginalCovariance`: 36 `f64`, the 6 × 6 matrix row-major in `Pose3`'s tangent order (rotation, then translation) |
//!
//! Factor types: `p` pose prior (`u64` key, pose, 6 `f64` sigmas rotation then
//! translation); `v` velocity prior (`u64` key, 3 `f64`, `f64` sigma); `b` bias prior
//! (`u64` key, bias, `f64` accelerometer sigma, `f64` gyroscope sigma); `B` between (`u64`
//! from, `u64` to, pose `from_from_to`, 6 sigmas, `u8` kernel 0 none, 1 Huber, 2 Cauchy,
//! `f64` kernel width); `P` position (`u64` key, 3 `f64` world position, 3 `f64` sigmas:
//! GTSAM's `GPSFactor`); `I` IMU (`u64` from, `u64` to, bias linearisation point, 6 `f64`:
//! accelerometer and gyroscope noise densities, their bias random walks, gravity m/s²,
//! integration covariance m²/s; `u64` n, then n samples of 7 `f64`: dt, specific force xyz,
//! angular rate xyz).
//!
//! The update's reply: `u64` variables, `u64` factors, `u64` iterations, `f64` error before,
//! `f64` error after (NaN for an incremental update: not evaluated); then the variables
//! ISAM2 took in this update: `u64` n, n × (`u8` kind, `u64` key).

// abi_stable's derives expand to `unsafe impl`s (StableAbi, the prefix type's accessors),
// and [`load`] reads the exported header from the library: the one unsafe block written here.
#![allow(unsafe_code)]
// Plain FFI data; nothing here is meant to be printed.
#![allow(missing_debug_implementations)]

use std::path::Path;

use abi_stable::library::{AbiHeaderRef, LibraryError, RawLibrary, RootModule};
use abi_stable::sabi_types::VersionStrings;
use abi_stable::std_types::{RResult, RSlice, RString, RVec};
use abi_stable::{StableAbi, declare_root_module_statics, package_version_strings};

/// The root module the bridge library exports.
#[repr(C)]
#[derive(StableAbi)]
#[sabi(kind(Prefix(prefix_ref = BridgeRef)))]
#[sabi(missing_field(panic))]
pub struct Bridge {
    /// Starts the interpreter and imports GTSAM (the first time), then makes a graph with
    /// the configuration; its handle, or why not.
    pub open: extern "C" fn(config: RSlice<'_, u8>) -> RResult<u64, RString>,
    /// One request on a graph.
    pub call: extern "C" fn(handle: u64, request: RSlice<'_, u8>) -> RResult<RVec<u8>, RString>,
    /// Drops a graph.
    #[sabi(last_prefix_field)]
    pub close: extern "C" fn(handle: u64),
}

impl RootModule for BridgeRef {
    declare_root_module_statics! {BridgeRef}
    const BASE_NAME: &'static str = "vinebench_gtsam";
    const NAME: &'static str = "vinebench_gtsam";
    // This crate's version: a bridge built against another minor version is refused.
    const VERSION_STRINGS: VersionStrings = package_version_strings!();
}

/// The symbol of the bridge's `abi_stable::library::LibHeader` (without the NUL).
pub const EXPORT_NAME: &str = "vinebench_gtsam_bridge_root";

/// Loads the bridge library at `path` (once per process: abi_stable keeps the first root
/// module of a type, and the library is never unloaded) and checks its version and layout.
pub fn load(path: &Path) -> Result<BridgeRef, LibraryError> {
    let raw = RawLibrary::load_at(path)?;
    let name = format!("{EXPORT_NAME}\0");
    // SAFETY: the bridge exports `EXPORT_NAME` as a `LibHeader` static, whose address is
    // what `get` returns as the `AbiHeaderRef` (the same read abi_stable's own
    // `abi_header_from_raw_library` does for its usual symbol); `upgrade` then checks the
    // header before anything else of it is used. The library is leaked below, so the
    // header's `'static` references stay valid.
    let header: AbiHeaderRef = unsafe { *raw.get::<AbiHeaderRef>(name.as_bytes())? };
    std::mem::forget(raw);
    header.upgrade()?.init_root_module::<BridgeRef>()
}

/// Appends protocol fields.
#[derive(Debug, Default, Clone)]
pub struct Writer(pub Vec<u8>);

impl Writer {
    pub fn new(op: u8) -> Self {
        Self(vec![op])
    }
    pub fn u8(&mut self, v: u8) -> &mut Self {
        self.0.push(v);
        self
    }
    pub fn u64(&mut self, v: u64) -> &mut Self {
        self.0.extend_from_slice(&v.to_le_bytes());
        self
    }
    pub fn f64(&mut self, v: f64) -> &mut Self {
        self.0.extend_from_slice(&v.to_le_bytes());
        self
    }
    pub fn f64s(&mut self, vs: &[f64]) -> &mut Self {
        vs.iter().for_each(|&v| {
            self.f64(v);
        });
        self
    }
}

/// Reads protocol fields; `None` past the end.
#[derive(Debug, Clone)]
pub struct Reader<'a> {
    buf: &'a [u8],
}

impl<'a> Reader<'a> {
    pub fn new(buf: &'a [u8]) -> Self {
        Self { buf }
    }
    fn take<const N: usize>(&mut self) -> Option<[u8; N]> {
        let (head, rest) = self.buf.split_first_chunk::<N>()?;
        self.buf = rest;
        Some(*head)
    }
    pub fn u8(&mut self) -> Option<u8> {
        self.take::<1>().map(|[b]| b)
    }
    pub fn u64(&mut self) -> Option<u64> {
        self.take::<8>().map(u64::from_le_bytes)
    }
    pub fn f64(&mut self) -> Option<f64> {
        self.take::<8>().map(f64::from_le_bytes)
    }
    pub fn f64s<const N: usize>(&mut self) -> Option<[f64; N]> {
        let mut out = [0.0; N];
        for v in &mut out {
            *v = self.f64()?;
        }
        Some(out)
    }
    pub fn is_empty(&self) -> bool {
        self.buf.is_empty()
    }
}
