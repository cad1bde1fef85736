//! [`GtsamBackend`]: the real GTSAM 4.3 (its ISAM2, Kaess et al., "iSAM2: Incremental
//! smoothing and mapping using the Bayes tree", IJRR 31(2), 2012, and its
//! CombinedImuFactor, Forster et al., "On-Manifold Preintegration for Real-Time
//! Visual-Inertial Odometry", IEEE T-RO 33(1), 2017), through the Python wrapper of the
//! `gtsam` wheel from PyPI, in a CPython that a bridge library embeds.
//!
//! Nothing here links Python: the bridge (`libvinebench_gtsam.so`, crate `vinebench-gtsam`)
//! is loaded when the first `"gtsam"` backend is made, from `VINEBENCH_GTSAM_LIB`, else
//! beside the running executable or in its parent directory (test binaries live in
//! `target/release/deps`). The bridge finds GTSAM in the virtual environment
//! `scripts/setup.sh` makes (`target/gtsam-venv`, or `VINEBENCH_GTSAM_VENV`). What is missing
//! (the bridge, libpython, the gtsam package) is one [`BackendError::Unavailable`] line.
//!
//! This side checks every input (as the factrs backend does), keeps every variable's
//! initial value and the estimates read since the last update, and encodes each call into
//! one request
//! of the bridge's byte protocol (`gtsam_ffi`); the bridge's Python half
//! (`plugins/gtsam-backend/src/bridge.py`) turns requests into GTSAM calls:
//!
//! - keys are `gtsam.symbol('x' | 'v' | 'b', key)`, so keys must be below 2⁵⁶;
//! - poses are `Pose3` `world_from_body`; [`PoseSigmas`](super::PoseSigmas) (rotation, then
//!   translation) is Pose3's tangent order; priors are `PriorFactorPose3`,
//!   `PriorFactorVector`, `PriorFactorConstantBias` (`imuBias.ConstantBias(accel, gyro)`,
//!   whose vector, like its sigmas, is accelerometer first); a between factor is
//!   `BetweenFactorPose3(x(from), x(to), from_from_to)`, with a kernel
//!   `noiseModel.Robust(mEstimator.Huber | Cauchy(k), Diagonal.Sigmas)`; a position factor
//!   is `GPSFactor(x(key), position, Diagonal.Sigmas)` (error `t(x) − position`, as ours);
//! - an IMU factor is GTSAM's `CombinedImuFactor` on `PreintegrationCombinedParams.
//!   MakeSharedU(g)` (gravity along −z), integrating each sample with
//!   `integrateMeasurement(accel, gyro, dt)` from the bias estimate of `from` when the
//!   factor is added. GTSAM takes continuous-time covariances: the densities squared
//!   (accelerometer and gyroscope white noise, bias random walks) and the integration
//!   covariance `imu::INTEGRATION_VARIANCE_PER_S`·I, the rate the factrs backend also
//!   uses (it multiplies it by each sample's dt, as GTSAM does);
//! - [`Scope::Incremental`] is one `ISAM2.update` with the factors, values and removals
//!   since the last one; [`Scope::Full`] is an update that relinearises every variable
//!   (`force_relinearize` with the relinearisation threshold set to 0 for it), repeated
//!   with nothing new until the error stops falling, at most `max_iterations` updates;
//! - `ISAM2Params`: the configuration's `relinearizeThreshold`, `relinearizeSkip` and,
//!   through `ISAM2GaussNewtonParams`, `wildfireThreshold`; Cholesky, Gauss–Newton;
//! - an estimate is ISAM2's `calculateEstimate(key)`, read when [`Backend::value`] first
//!   asks for it after an update (an update does not copy the whole estimate back, which
//!   would cost a pass over the graph per update); variables no factor uses yet are held
//!   back from ISAM2 (which refuses them) and keep their initial value;
//! - [`Backend::factor_error`] is `sqrt(2·error)` of the factor without its kernel at the
//!   current estimate; [`Backend::remove`] queues the factor's ISAM2 index for the next
//!   update (or drops it if it has not reached ISAM2 yet);
//! - [`Backend::set_value`] works only for a variable ISAM2 has not taken yet: ISAM2 has no
//!   way to overwrite its linearisation point;
//! - [`Backend::marginal_covariance`] is ISAM2's `marginalCovariance(x(key))`: from its Bayes
//!   tree at the linearisation point, in `Pose3`'s tangent order (rotation, then
//!   translation, both in the body frame), ours; a pose ISAM2 has not taken yet has none.
//!
//! The update report: `variables` = variables ISAM2 re-eliminated (all of them for a full
//! update), `factors` = factors it relinearised (ISAM2Result's counts), `iterations` =
//! ISAM2 updates; for a full update `error_before`/`error_after` = 2 × GTSAM's nonlinear
//! error (Σ ½‖r‖², the kernel's ρ for robust factors) of every factor at the estimate
//! before and after; an incremental update does not evaluate them (NaN), as GTSAM with its
//! default `evaluateNonlinearError = false`: it would cost a pass over the graph.

use std::cell::RefCell;
use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};
use std::sync::OnceLock;

use gtsam_ffi::{BridgeRef, Reader, Writer};
use nalgebra::{Isometry3, Matrix3, Matrix6, Rotation3, Translation3, UnitQuaternion, Vector3};

use super::entry::{check, vars_of};
use super::{
    Backend, BackendConfig, BackendError, Factor, FactorId, ImuBias, PoseCovariance, Robust, Scope,
    UpdateReport, Value, Var, convert, imu::INTEGRATION_VARIANCE_PER_S,
};

/// The bridge library's file name (cargo's name for the `vinebench_gtsam` cdylib).
fn bridge_file() -> String {
    use std::env::consts::{DLL_PREFIX, DLL_SUFFIX};
    format!("{DLL_PREFIX}vinebench_gtsam{DLL_SUFFIX}")
}
const SETUP_HINT: &str = "run `bash scripts/setup.sh`";
/// GTSAM's `Symbol` keeps 56 bits for the index.
const KEY_LIMIT: u64 = 1 << 56;

/// The factor-graph backend on GTSAM's own ISAM2; how it works is in this file's module
/// documentation.
pub struct GtsamBackend {
    bridge: BridgeRef,
    handle: u64,
    /// The estimate of every variable, ISAM2's or (not yet in ISAM2) the initial one.
    vars: BTreeMap<Var, Value>,
    /// Variables ISAM2 holds.
    in_isam: BTreeSet<Var>,
    /// Estimates fetched since the last update.
    cache: RefCell<BTreeMap<Var, Value>>,
    factors: BTreeSet<FactorId>,
    next_factor: u64,
}

impl std::fmt::Debug for GtsamBackend {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("GtsamBackend")
            .field("handle", &self.handle)
            .field("variables", &self.vars.len())
            .field("factors", &self.factors.len())
            .finish_non_exhaustive()
    }
}

impl Drop for GtsamBackend {
    fn drop(&mut self) {
        (self.bridge.close())(self.handle);
    }
}

impl GtsamBackend {
    /// Loads the bridge (once per process) and makes an empty graph with the
    /// configuration's iSAM2 settings.
    pub fn new(config: &BackendConfig) -> Result<Self, BackendError> {
        let finite_nonneg = |what: &str, x: f64| {
            if x.is_finite() && x >= 0.0 {
                Ok(())
            } else {
                Err(BackendError::Invalid(format!(
                    "{what} must be finite and not negative, got {x}"
                )))
            }
        };
        finite_nonneg("relinearize_threshold", config.relinearize_threshold)?;
        finite_nonneg("wildfire_threshold", config.wildfire_threshold)?;
        let bridge = bridge()?;
        let mut w = Writer::default();
        w.f64(config.relinearize_threshold)
            .u64(config.relinearize_skip.max(1) as u64)
            .f64(config.wildfire_threshold)
            .u64(config.max_iterations.max(1) as u64);
        let handle = (bridge.open())(w.0.as_slice().into())
            .into_result()
            .map_err(|e| BackendError::Unavailable(e.into_string()))?;
        Ok(Self {
            bridge,
            handle,
            vars: BTreeMap::new(),
            in_isam: BTreeSet::new(),
            cache: RefCell::new(BTreeMap::new()),
            factors: BTreeSet::new(),
            next_factor: 0,
        })
    }

    fn call(&self, request: &Writer) -> Result<Vec<u8>, BackendError> {
        (self.bridge.call())(self.handle, request.0.as_slice().into())
            .into_result()
            .map(|v| v.into_vec())
            .map_err(|e| BackendError::Solver(e.into_string()))
    }

    fn bias(&self, key: u64) -> Option<ImuBias> {
        match self.value(Var::Bias(key))? {
            Value::Bias(b) => Some(b),
            _ => None,
        }
    }

    /// Reads an update's reply: the report, and the variables ISAM2 took in this update.
    /// Estimates are asked for one variable at a time afterwards ([`Backend::value`]).
    fn take_update(&mut self, reply: &[u8]) -> Option<UpdateReport> {
        let mut r = Reader::new(reply);
        let report = UpdateReport {
            variables: r.u64()? as usize,
            factors: r.u64()? as usize,
            iterations: r.u64()? as usize,
            error_before: r.f64()?,
            error_after: r.f64()?,
        };
        let n = r.u64()? as usize;
        let mut taken = Vec::with_capacity(n);
        for _ in 0..n {
            let kind = r.u8()?;
            let key = r.u64()?;
            taken.push(match kind {
                b'x' => Var::Pose(key),
                b'v' => Var::Velocity(key),
                b'b' => Var::Bias(key),
                _ => return None,
            });
        }
        if !r.is_empty() {
            return None;
        }
        self.in_isam.extend(taken);
        self.cache.borrow_mut().clear();
        Some(report)
    }

    /// ISAM2's current estimate of a variable it holds (GTSAM's `calculateEstimate(key)`).
    fn estimate(&self, var: Var) -> Option<Value> {
        let (kind, key) = kind_and_key(var);
        let mut w = Writer::new(b'v');
        w.u8(kind).u64(key);
        let reply = self.call(&w).ok()?;
        let mut r = Reader::new(&reply);
        let value = match var {
            Var::Pose(_) => {
                let m: [f64; 12] = r.f64s()?;
                let rot = Matrix3::new(m[0], m[1], m[2], m[3], m[4], m[5], m[6], m[7], m[8]);
                let rot =
                    UnitQuaternion::from_rotation_matrix(&Rotation3::from_matrix_unchecked(rot));
                let t = Translation3::new(m[9], m[10], m[11]);
                Value::Pose(Isometry3::from_parts(t, rot))
            }
            Var::Velocity(_) => Value::Velocity(Vector3::from(r.f64s::<3>()?)),
            Var::Bias(_) => {
                let b: [f64; 6] = r.f64s()?;
                Value::Bias(ImuBias {
                    accel_mps2: Vector3::new(b[0], b[1], b[2]),
                    gyro_rps: Vector3::new(b[3], b[4], b[5]),
                })
            }
        };
        r.is_empty().then_some(value)
    }
}

/// The bridge, loaded on first use; a failure is remembered (it will not go away while
/// the process runs).
fn bridge() -> Result<BridgeRef, BackendError> {
    static BRIDGE: OnceLock<Result<BridgeRef, String>> = OnceLock::new();
    BRIDGE
        .get_or_init(|| {
            let path = bridge_path()?;
            gtsam_ffi::load(&path).map_err(|e| load_error(&path, &e.to_string()))
        })
        .clone()
        .map_err(BackendError::Unavailable)
}

fn bridge_path() -> Result<PathBuf, String> {
    if let Some(p) = std::env::var_os("VINEBENCH_GTSAM_LIB") {
        let p = PathBuf::from(p);
        return if p.is_file() {
            Ok(p)
        } else {
            Err(format!(
                "GTSAM backend: VINEBENCH_GTSAM_LIB={} is not a file",
                p.display()
            ))
        };
    }
    let exe_dir = std::env::current_exe()
        .ok()
        .and_then(|p| p.parent().map(Path::to_owned));
    let dirs: Vec<PathBuf> = exe_dir
        .iter()
        .flat_map(|d| [Some(d.clone()), d.parent().map(Path::to_owned)])
        .flatten()
        .collect();
    dirs.iter()
        .map(|d| d.join(bridge_file()))
        .find(|p| p.is_file())
        .ok_or_else(|| {
            let looked: Vec<String> = dirs.iter().map(|d| d.display().to_string()).collect();
            format!(
                "GTSAM backend: bridge library {} not found in {} (build it with `cargo build --release -p vinebench-gtsam`, or set VINEBENCH_GTSAM_LIB)",
                bridge_file(),
                looked.join(", ")
            )
        })
}

fn load_error(path: &Path, error: &str) -> String {
    let line = error.lines().find(|l| !l.trim().is_empty()).unwrap_or("");
    if line.contains("libpython") {
        format!(
            "GTSAM backend: libpython is missing for {} ({}): {SETUP_HINT} (it installs python3-dev)",
            path.display(),
            line.trim()
        )
    } else {
        format!(
            "GTSAM backend: cannot load {}: {}",
            path.display(),
            line.trim()
        )
    }
}

fn same_kind(var: Var, value: &Value) -> bool {
    matches!(
        (var, value),
        (Var::Pose(_), Value::Pose(_))
            | (Var::Velocity(_), Value::Velocity(_))
            | (Var::Bias(_), Value::Bias(_))
    )
}

fn kind_and_key(var: Var) -> (u8, u64) {
    match var {
        Var::Pose(k) => (b'x', k),
        Var::Velocity(k) => (b'v', k),
        Var::Bias(k) => (b'b', k),
    }
}

fn pose(w: &mut Writer, p: &Isometry3<f64>) {
    let q = p.rotation.quaternion();
    let t = p.translation.vector;
    w.f64s(&[q.w, q.i, q.j, q.k, t.x, t.y, t.z]);
}

fn bias(w: &mut Writer, b: &ImuBias) {
    w.f64s(b.accel_mps2.as_slice()).f64s(b.gyro_rps.as_slice());
}

fn value(w: &mut Writer, v: &Value) {
    match v {
        Value::Pose(p) => pose(w, p),
        Value::Velocity(v) => {
            w.f64s(v.as_slice());
        }
        Value::Bias(b) => bias(w, b),
    }
}

/// The `a` request for a checked factor whose variables all exist.
fn encode(id: FactorId, f: &Factor, from_bias: Option<ImuBias>) -> Writer {
    let mut w = Writer::new(b'a');
    w.u64(id.0);
    match f {
        Factor::PosePrior {
            key,
            world_from_body,
            sigmas,
        } => {
            w.u8(b'p').u64(*key);
            pose(&mut w, world_from_body);
            w.f64s(sigmas.as_slice());
        }
        Factor::VelocityPrior {
            key,
            velocity_mps,
            sigma_mps,
        } => {
            w.u8(b'v')
                .u64(*key)
                .f64s(velocity_mps.as_slice())
                .f64(*sigma_mps);
        }
        Factor::BiasPrior {
            key,
            bias: b,
            sigma_accel,
            sigma_gyro,
        } => {
            w.u8(b'b').u64(*key);
            bias(&mut w, b);
            w.f64(*sigma_accel).f64(*sigma_gyro);
        }
        Factor::Position {
            key,
            position,
            sigmas,
        } => {
            w.u8(b'P')
                .u64(*key)
                .f64s(position.as_slice())
                .f64s(sigmas.as_slice());
        }
        Factor::Between {
            from,
            to,
            from_from_to,
            sigmas,
            robust,
        } => {
            w.u8(b'B').u64(*from).u64(*to);
            pose(&mut w, from_from_to);
            w.f64s(sigmas.as_slice());
            let (kernel, k) = match robust {
                Robust::None => (0, 0.0),
                Robust::Huber(k) => (1, *k),
                Robust::Cauchy(k) => (2, *k),
            };
            w.u8(kernel).f64(k);
        }
        Factor::Imu {
            from,
            to,
            samples,
            noise,
        } => {
            w.u8(b'I').u64(*from).u64(*to);
            bias(&mut w, &from_bias.unwrap_or_default());
            w.f64s(&[
                noise.accel_noise_density,
                noise.gyro_noise_density,
                noise.accel_bias_random_walk,
                noise.gyro_bias_random_walk,
                noise.gravity_mps2,
                INTEGRATION_VARIANCE_PER_S,
            ]);
            w.u64(samples.len() as u64);
            for s in samples {
                w.f64(s.dt_s)
                    .f64s(s.accel_mps2.as_slice())
                    .f64s(s.gyro_rps.as_slice());
            }
        }
    }
    w
}

fn protocol_error(what: &str) -> BackendError {
    BackendError::Solver(format!("GTSAM bridge: malformed reply to {what}"))
}

impl Backend for GtsamBackend {
    fn insert(&mut self, var: Var, initial: Value) -> Result<(), BackendError> {
        if !same_kind(var, &initial) {
            return Err(BackendError::Invalid(format!(
                "{var:?} cannot hold {initial:?}"
            )));
        }
        convert::check_value(&initial)?;
        let (kind, key) = kind_and_key(var);
        if key >= KEY_LIMIT {
            return Err(BackendError::Invalid(format!(
                "{var:?}: GTSAM keys must be below 2^56"
            )));
        }
        if self.vars.contains_key(&var) {
            return Err(BackendError::Duplicate(var));
        }
        let mut w = Writer::new(b'i');
        w.u8(kind).u64(key);
        value(&mut w, &initial);
        self.call(&w)?;
        self.vars.insert(var, initial);
        Ok(())
    }

    fn add(&mut self, factor: Factor) -> Result<FactorId, BackendError> {
        // The checks the factrs backend makes, on the same terms: what GTSAM would turn
        // into NaN or an exception.
        check(&factor)?;
        if let Some(missing) = vars_of(&factor)
            .into_iter()
            .find(|v| !self.vars.contains_key(v))
        {
            return Err(BackendError::MissingVariable(missing));
        }
        let from_bias = match &factor {
            Factor::Imu { from, .. } => self.bias(*from),
            _ => None,
        };
        let id = FactorId(self.next_factor);
        self.call(&encode(id, &factor, from_bias))?;
        self.next_factor += 1;
        self.factors.insert(id);
        Ok(id)
    }

    fn remove(&mut self, id: FactorId) -> bool {
        if !self.factors.remove(&id) {
            return false;
        }
        let mut w = Writer::new(b'r');
        w.u64(id.0);
        matches!(self.call(&w).as_deref(), Ok([1]))
    }

    fn update(&mut self, scope: Scope) -> Result<UpdateReport, BackendError> {
        let mut w = Writer::new(b'u');
        w.u8(u8::from(scope == Scope::Full));
        let reply = self.call(&w)?;
        self.take_update(&reply)
            .ok_or_else(|| protocol_error("update"))
    }

    fn value(&self, var: Var) -> Option<Value> {
        if !self.in_isam.contains(&var) {
            return self.vars.get(&var).copied();
        }
        if let Some(v) = self.cache.borrow().get(&var) {
            return Some(*v);
        }
        let v = self.estimate(var)?;
        self.cache.borrow_mut().insert(var, v);
        Some(v)
    }

    fn set_value(&mut self, var: Var, value: Value) -> Result<(), BackendError> {
        if !same_kind(var, &value) {
            return Err(BackendError::Invalid(format!(
                "{var:?} cannot hold {value:?}"
            )));
        }
        convert::check_value(&value)?;
        if !self.vars.contains_key(&var) {
            return Err(BackendError::MissingVariable(var));
        }
        if self.in_isam.contains(&var) {
            return Err(BackendError::Invalid(format!(
                "the gtsam backend cannot set {var:?}: GTSAM's ISAM2 cannot overwrite the estimate of a variable it holds"
            )));
        }
        // Not in ISAM2 yet: the new value replaces the initial one it will be given.
        let (kind, key) = kind_and_key(var);
        let mut w = Writer::new(b'i');
        w.u8(kind).u64(key);
        self::value(&mut w, &value);
        self.call(&w)?;
        self.vars.insert(var, value);
        Ok(())
    }

    fn factor_error(&self, id: FactorId) -> Option<f64> {
        if !self.factors.contains(&id) {
            return None;
        }
        let mut w = Writer::new(b'e');
        w.u64(id.0);
        let reply = self.call(&w).ok()?;
        let mut r = Reader::new(&reply);
        match r.u8()? {
            1 => r.f64(),
            _ => None,
        }
    }

    fn pose_keys(&self) -> Vec<u64> {
        self.vars
            .range(Var::Pose(0)..=Var::Pose(u64::MAX))
            .map(|(v, _)| kind_and_key(*v).1)
            .collect()
    }

    fn marginal_covariance(&self, key: u64) -> Result<PoseCovariance, BackendError> {
        let var = Var::Pose(key);
        if !self.vars.contains_key(&var) {
            return Err(BackendError::MissingVariable(var));
        }
        if !self.in_isam.contains(&var) {
            return Err(BackendError::Invalid(format!(
                "no marginal of pose {key}: no update has given it to ISAM2 yet"
            )));
        }
        let mut w = Writer::new(b'c');
        w.u8(b'x').u64(key);
        let reply = self.call(&w)?;
        let mut r = Reader::new(&reply);
        let m: [f64; 36] = r
            .f64s()
            .ok_or_else(|| protocol_error("marginal covariance"))?;
        if !r.is_empty() {
            return Err(protocol_error("marginal covariance"));
        }
        let world_from_body = self.pose(key).ok_or(BackendError::MissingVariable(var))?;
        Ok(PoseCovariance {
            tangent: Matrix6::from_row_slice(&m),
            world_from_body,
        })
    }
}
