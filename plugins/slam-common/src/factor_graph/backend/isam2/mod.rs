//! [`Isam2Backend`]: incremental smoothing and mapping on a Bayes tree, after Kaess,
//! Johannsson, Roberts, Ila, Leonard and Dellaert, "iSAM2: Incremental Smoothing and
//! Mapping Using the Bayes Tree", IJRR 31(2):216–235, 2012, with GTSAM's documented
//! parameters (`ISAM2Params`: relinearisation threshold 0.1 checked every 10th update,
//! wildfire threshold 0.001, Cholesky elimination, Gauss–Newton steps).
//!
//! The state is a linearisation point `θ` for every variable, the current step `δ`
//! (estimate `θ ⊕ δ`, right perturbations as in [`convert`](super::convert)), every
//! factor with its cached linearisation, and the Bayes tree (module `tree`) of the
//! linearised graph. An update (the paper's Algorithm 2 with Algorithms 4 and 5):
//! 1. *Fluid relinearisation*: every `relinearize_skip`-th update, the variables whose
//!    step exceeds `relinearize_threshold` in any component get `θ ← θ ⊕ δ`.
//! 2. *Which cliques go*: those holding a variable of a new or removed factor, and those
//!    that absorbed a factor touching a relinearised variable, with all their ancestors
//!    (the "top"); the subtrees hanging below become orphans, each summarised by the
//!    marginal factor it passed up when it was eliminated.
//! 3. The top's variables are re-ordered (constrained minimum degree, the newest factors'
//!    variables last, module `ordering`) and re-eliminated from the factors lying
//!    entirely among them (relinearised where needed) and the orphans' marginals; the
//!    orphans are re-attached under the clique of their first eliminated separator
//!    variable.
//! 4. *Partial (wildfire) back-substitution*: from the roots, a clique is re-solved if it
//!    is new or one of its separator variables moved by more than `wildfire_threshold`;
//!    descent stops where nothing moved.
//!
//! Cliques are fundamental supernodes (module `tree`), as GTSAM's. [`Scope::Full`] relinearises every variable and
//! re-eliminates the whole graph, repeated while the error falls (Gauss–Newton to
//! convergence, at most `max_iterations` times). Factors are linearised by factrs
//! (automatic differentiation of the same residuals the factrs backend uses; robust
//! kernels by iterative reweighting, as GTSAM's `Robust` noise model). Removing a factor
//! takes effect at the next update.
//!
//! A pose's marginal covariance comes from the Bayes tree as of the last update, top-down
//! from the root to the pose's clique ([`BayesTree::covariance`], what GTSAM's
//! `ISAM2::marginalCovariance` does): cheap for the newest poses, which the constrained
//! ordering keeps in the root. The factrs backend uses the same elimination on its whole
//! graph ([`covariance_of`]).

mod linear;
mod ordering;
mod tree;

use std::collections::{BTreeMap, BTreeSet};

use ::factrs::containers::{Key, Values};
use ::factrs::variables::Variable;
use nalgebra::{DMatrix, DVector, Isometry3, Matrix6};

use super::{
    Backend, BackendConfig, BackendError, Factor, FactorId, ImuBias, PoseCovariance, Scope,
    UpdateReport, Value, Var, convert, entry::Entry, solve,
};
use linear::InfoFactor;
use tree::BayesTree;

/// Stop a full update when an iteration lowers the error by less than this fraction.
const RELATIVE_TOLERANCE: f64 = 1e-6;

#[derive(Debug, Clone)]
struct VarState {
    var: Var,
    /// Linearisation point.
    theta: Value,
    /// Live factors touching it.
    factors: Vec<usize>,
}

#[derive(Debug, Clone)]
struct FactorState {
    entry: Entry,
    vars: Vec<usize>,
    /// Linearised at the variables' current `theta`; `None` when one of them moved.
    linear: Option<InfoFactor>,
}

/// The native iSAM2 backend; how it works is in this module's documentation.
#[derive(Debug, Clone)]
pub struct Isam2Backend {
    relinearize_threshold: f64,
    relinearize_skip: usize,
    wildfire_threshold: f64,
    max_iterations: usize,
    vars: Vec<VarState>,
    /// Each variable's current step from its `theta`.
    delta: Vec<DVector<f64>>,
    /// Each variable's tangent dimension.
    dims: Vec<usize>,
    ids: BTreeMap<Var, usize>,
    /// By `FactorId`; `None` once removed.
    factors: Vec<Option<FactorState>>,
    /// Factors added since the last update.
    new_factors: Vec<usize>,
    /// Variables of factors removed since the last update.
    removed_vars: BTreeSet<usize>,
    /// Variables whose estimate was set by hand since the last update.
    reset: BTreeSet<usize>,
    tree: BayesTree,
    updates: u64,
}

impl Isam2Backend {
    /// An empty graph with the configuration's iSAM2 parameters.
    pub fn new(config: &BackendConfig) -> Self {
        Self {
            relinearize_threshold: config.relinearize_threshold,
            relinearize_skip: config.relinearize_skip,
            wildfire_threshold: config.wildfire_threshold,
            max_iterations: config.max_iterations.max(1),
            vars: Vec::new(),
            delta: Vec::new(),
            dims: Vec::new(),
            ids: BTreeMap::new(),
            factors: Vec::new(),
            new_factors: Vec::new(),
            removed_vars: BTreeSet::new(),
            reset: BTreeSet::new(),
            tree: BayesTree::default(),
            updates: 0,
        }
    }

    fn estimate(&self, i: usize) -> Value {
        retract(&self.vars[i].theta, &self.delta[i])
    }

    fn bias(&self, key: u64) -> Option<ImuBias> {
        match self.estimate(*self.ids.get(&Var::Bias(key))?) {
            Value::Bias(b) => Some(b),
            _ => None,
        }
    }

    /// One iSAM2 update; `all` relinearises every variable (a Gauss–Newton iteration on
    /// the whole graph).
    fn step(&mut self, all: bool) -> Result<UpdateReport, BackendError> {
        self.updates += 1;
        // 1. Which variables to relinearise.
        let mut relin: BTreeSet<usize> = self.reset.clone();
        let check = self.relinearize_skip == 0 || self.updates % self.relinearize_skip as u64 == 0;
        if all || check {
            for (i, delta) in self.delta.iter().enumerate() {
                if self.tree.contains(i) && (all || delta.amax() >= self.relinearize_threshold) {
                    relin.insert(i);
                }
            }
        }
        // 2. Variables whose cliques (and ancestors) are re-eliminated.
        let mut marked: BTreeSet<usize> = self.removed_vars.clone();
        let mut observed: BTreeSet<usize> = BTreeSet::new();
        for &f in &self.new_factors {
            if let Some(state) = &self.factors[f] {
                observed.extend(state.vars.iter().copied());
            }
        }
        marked.extend(observed.iter().copied());
        for &j in &relin {
            for &f in &self.vars[j].factors {
                if let Some(state) = &self.factors[f] {
                    marked.extend(state.vars.iter().copied());
                }
            }
            marked.insert(j);
        }
        let removed = self.tree.top(&marked);
        let mut top: BTreeSet<usize> = removed.vars.clone();
        top.extend(
            marked
                .iter()
                .copied()
                .filter(|&i| !self.tree.contains(i) && !self.vars[i].factors.is_empty()),
        );
        // Relinearised linearisation points, applied only if the update succeeds.
        let thetas: BTreeMap<usize, Value> = relin.iter().map(|&j| (j, self.estimate(j))).collect();
        let theta = |i: usize| thetas.get(&i).copied().unwrap_or(self.vars[i].theta);
        // 3. The factors lying entirely in the top, linearised at the new points.
        let mut gathered: BTreeSet<usize> = BTreeSet::new();
        for &i in &top {
            for &f in &self.vars[i].factors {
                if let Some(state) = &self.factors[f]
                    && state.vars.iter().all(|v| top.contains(v))
                {
                    gathered.insert(f);
                }
            }
        }
        let mut linearised: Vec<(usize, InfoFactor)> = Vec::new();
        for &f in &gathered {
            let Some(state) = &self.factors[f] else {
                continue;
            };
            let stale = state.linear.is_none() || state.vars.iter().any(|v| relin.contains(v));
            if stale {
                linearised.push((f, self.linearise(state, &theta)?));
            }
        }
        let fresh: BTreeMap<usize, &InfoFactor> = linearised.iter().map(|(f, l)| (*f, l)).collect();
        let mut inputs: Vec<&InfoFactor> =
            Vec::with_capacity(gathered.len() + removed.orphans.len());
        for &f in &gathered {
            match fresh.get(&f) {
                Some(l) => inputs.push(l),
                None => {
                    if let Some(FactorState {
                        linear: Some(l), ..
                    }) = &self.factors[f]
                    {
                        inputs.push(l);
                    }
                }
            }
        }
        for &o in &removed.orphans {
            if let Some(m) = self.tree.marginal(o) {
                inputs.push(m);
            }
        }
        let error_before: f64 = inputs.iter().map(|f| f.constant()).sum();
        // 4. Order and eliminate the top.
        let top_vars: Vec<usize> = top.iter().copied().collect();
        let last: BTreeSet<usize> = observed.intersection(&top).copied().collect();
        let order = ordering::constrained_min_degree(
            &top_vars,
            inputs.iter().map(|f| f.keys.as_slice()),
            &last,
        );
        let eliminated = tree::eliminate(&order, &inputs, &self.dims).map_err(|i| {
            BackendError::Solver(format!(
                "indeterminate system: {:?} is not constrained (no prior?)",
                self.vars[i].var
            ))
        })?;
        let error_after = eliminated.leftover;
        // Commit: new points, cached linearisations, the tree.
        for (j, value) in thetas {
            self.vars[j].theta = value;
            self.delta[j].fill(0.0);
        }
        for (f, l) in linearised {
            if let Some(state) = &mut self.factors[f] {
                state.linear = Some(l);
            }
        }
        let new_cliques: BTreeSet<usize> = self
            .tree
            .replace_top(&removed, eliminated)
            .into_iter()
            .collect();
        self.new_factors.clear();
        self.removed_vars.clear();
        self.reset.clear();
        // 5. Wildfire back-substitution.
        self.tree
            .back_substitute(&new_cliques, &mut self.delta, self.wildfire_threshold);
        Ok(UpdateReport {
            variables: top.len(),
            factors: gathered.len(),
            iterations: 1,
            error_before,
            error_after,
        })
    }

    /// The factor linearised at the points `theta` gives, as an information factor.
    fn linearise(
        &self,
        state: &FactorState,
        theta: &impl Fn(usize) -> Value,
    ) -> Result<InfoFactor, BackendError> {
        let mut values = Values::new();
        for &i in &state.vars {
            solve::insert(&mut values, Key(i as u64), &theta(i));
        }
        let key = |v: Var| Key(self.ids.get(&v).map_or(u64::MAX, |&i| i as u64));
        let factor = state.entry.build(key, true);
        linearise(&factor, &values, &self.dims).ok_or_else(|| {
            BackendError::Solver(format!(
                "a factor on {:?} linearised to non-finite values",
                state
                    .vars
                    .iter()
                    .map(|&i| self.vars[i].var)
                    .collect::<Vec<_>>()
            ))
        })
    }

    /// Twice GTSAM's error of every factor at the current estimate (robust factors by
    /// their kernel).
    fn total_error(&self) -> f64 {
        let mut total = 0.0;
        for state in self.factors.iter().flatten() {
            let mut values = Values::new();
            for &i in &state.vars {
                solve::insert(&mut values, Key(i as u64), &self.estimate(i));
            }
            let key = |v: Var| Key(self.ids.get(&v).map_or(u64::MAX, |&i| i as u64));
            total += 2.0 * state.entry.build(key, true).error(&values);
        }
        total
    }
}

/// A factrs factor linearised at `values` (keys: variable indices into `dims`), as an
/// information factor; `None` if it linearised to something not finite.
pub(crate) fn linearise(
    factor: &::factrs::containers::Factor,
    values: &Values,
    dims: &[usize],
) -> Option<InfoFactor> {
    let linear = factor.linearize(values);
    let keys: Vec<usize> = linear.keys.iter().map(|k| k.0 as usize).collect();
    let key_dims: Vec<usize> = keys.iter().map(|&i| dims[i]).collect();
    let a = DMatrix::from(linear.a.mat().clone_owned());
    let b = DVector::from(linear.b.clone());
    if a.iter().chain(b.iter()).any(|x| !x.is_finite()) {
        return None;
    }
    Some(InfoFactor::from_jacobian(keys, key_dims, &a, &b))
}

/// The covariance of variable `target`'s step given the linearised `factors` (variable
/// indices into `dims`): the whole system eliminated with `target` last (constrained
/// minimum degree, module `ordering`), so that it ends in the root clique, and its block
/// read from the Bayes tree ([`BayesTree::covariance`]). `Err(variable)` names a variable
/// the factors leave unconstrained.
pub(crate) fn covariance_of(
    factors: &[InfoFactor],
    dims: &[usize],
    target: usize,
) -> Result<DMatrix<f64>, usize> {
    let vars: Vec<usize> = factors
        .iter()
        .flat_map(|f| f.keys.iter().copied())
        .collect::<BTreeSet<usize>>()
        .into_iter()
        .collect();
    if !vars.contains(&target) {
        return Err(target);
    }
    let last: BTreeSet<usize> = [target].into();
    let order =
        ordering::constrained_min_degree(&vars, factors.iter().map(|f| f.keys.as_slice()), &last);
    let inputs: Vec<&InfoFactor> = factors.iter().collect();
    let eliminated = tree::eliminate(&order, &inputs, dims)?;
    let mut bayes = BayesTree::default();
    bayes.replace_top(&tree::Top::default(), eliminated);
    bayes.covariance(target, dims).ok_or(target)
}

/// `θ ⊕ δ` with factrs's retractions (poses on the right, tangent rotation first; biases
/// gyroscope first).
fn retract(theta: &Value, delta: &DVector<f64>) -> Value {
    if delta.iter().all(|&x| x == 0.0) {
        return *theta;
    }
    match theta {
        Value::Pose(p) => Value::Pose(convert::iso_from_se3(
            &convert::se3_from_iso(p).oplus(delta.as_view()),
        )),
        Value::Velocity(v) => Value::Velocity(v + delta.fixed_rows::<3>(0)),
        Value::Bias(b) => Value::Bias(ImuBias {
            gyro_rps: b.gyro_rps + delta.fixed_rows::<3>(0),
            accel_mps2: b.accel_mps2 + delta.fixed_rows::<3>(3),
        }),
    }
}

fn dim_of(var: Var) -> usize {
    match var {
        Var::Pose(_) | Var::Bias(_) => 6,
        Var::Velocity(_) => 3,
    }
}

impl Backend for Isam2Backend {
    fn insert(&mut self, var: Var, initial: Value) -> Result<(), BackendError> {
        super::factrs::check_value(var, &initial)?;
        if self.ids.contains_key(&var) {
            return Err(BackendError::Duplicate(var));
        }
        let dim = dim_of(var);
        self.ids.insert(var, self.vars.len());
        self.vars.push(VarState {
            var,
            theta: initial,
            factors: Vec::new(),
        });
        self.delta.push(DVector::zeros(dim));
        self.dims.push(dim);
        Ok(())
    }

    fn add(&mut self, factor: Factor) -> Result<FactorId, BackendError> {
        let entry = Entry::new(factor, |k| self.bias(k))?;
        let mut vars = Vec::with_capacity(entry.vars().len());
        for v in entry.vars() {
            vars.push(*self.ids.get(v).ok_or(BackendError::MissingVariable(*v))?);
        }
        let f = self.factors.len();
        for &i in &vars {
            self.vars[i].factors.push(f);
        }
        self.factors.push(Some(FactorState {
            entry,
            vars,
            linear: None,
        }));
        self.new_factors.push(f);
        Ok(FactorId(f as u64))
    }

    fn remove(&mut self, id: FactorId) -> bool {
        let Some(slot) = self.factors.get_mut(id.0 as usize) else {
            return false;
        };
        let Some(state) = slot.take() else {
            return false;
        };
        let f = id.0 as usize;
        for &i in &state.vars {
            self.vars[i].factors.retain(|&x| x != f);
        }
        self.new_factors.retain(|&x| x != f);
        self.removed_vars.extend(state.vars.iter().copied());
        true
    }

    fn update(&mut self, scope: Scope) -> Result<UpdateReport, BackendError> {
        match scope {
            Scope::Incremental => self.step(false),
            Scope::Full => {
                let mut report = self.step(true)?;
                let mut previous = self.total_error();
                let first_error = report.error_before;
                for _ in 1..self.max_iterations {
                    let r = self.step(true)?;
                    report.iterations += 1;
                    report.variables = report.variables.max(r.variables);
                    report.factors = report.factors.max(r.factors);
                    let error = self.total_error();
                    let decrease = previous - error;
                    previous = error;
                    if decrease <= RELATIVE_TOLERANCE * error.max(f64::MIN_POSITIVE) {
                        break;
                    }
                }
                report.error_before = first_error;
                report.error_after = previous;
                Ok(report)
            }
        }
    }

    fn value(&self, var: Var) -> Option<Value> {
        self.ids.get(&var).map(|&i| self.estimate(i))
    }

    fn set_value(&mut self, var: Var, value: Value) -> Result<(), BackendError> {
        super::factrs::check_value(var, &value)?;
        let &i = self
            .ids
            .get(&var)
            .ok_or(BackendError::MissingVariable(var))?;
        let v = &mut self.vars[i];
        v.theta = value;
        self.delta[i].fill(0.0);
        for &f in &v.factors {
            if let Some(state) = &mut self.factors[f] {
                state.linear = None;
            }
        }
        // Its cliques are re-eliminated at the next update, as for a relinearisation.
        if self.tree.contains(i) {
            self.reset.insert(i);
        }
        Ok(())
    }

    fn factor_error(&self, id: FactorId) -> Option<f64> {
        let state = self.factors.get(id.0 as usize)?.as_ref()?;
        let mut values = Values::new();
        for &i in &state.vars {
            solve::insert(&mut values, Key(i as u64), &self.estimate(i));
        }
        let key = |v: Var| Key(self.ids.get(&v).map_or(u64::MAX, |&i| i as u64));
        let half_sq = state.entry.build(key, false).error(&values);
        Some((2.0 * half_sq).sqrt())
    }

    fn pose_keys(&self) -> Vec<u64> {
        self.ids
            .range(Var::Pose(0)..=Var::Pose(u64::MAX))
            .map(|(v, _)| super::scope::keyframe(*v))
            .collect()
    }

    /// From the Bayes tree as of the last update, at its linearisation point
    /// (`BayesTree::covariance`), as GTSAM's `ISAM2::marginalCovariance`.
    fn marginal_covariance(&self, key: u64) -> Result<PoseCovariance, BackendError> {
        let var = Var::Pose(key);
        let &i = self
            .ids
            .get(&var)
            .ok_or(BackendError::MissingVariable(var))?;
        if !self.tree.contains(i) {
            return Err(BackendError::Invalid(format!(
                "no marginal of pose {key}: no update has taken it yet"
            )));
        }
        let cov = self.tree.covariance(i, &self.dims).ok_or_else(|| {
            BackendError::Solver(format!("the Bayes tree has no marginal of pose {key}"))
        })?;
        let world_from_body = self.pose(key).ok_or(BackendError::MissingVariable(var))?;
        Ok(PoseCovariance {
            tangent: Matrix6::from_fn(|r, c| cov[(r, c)]),
            world_from_body,
        })
    }

    fn pose(&self, key: u64) -> Option<Isometry3<f64>> {
        match self.value(Var::Pose(key))? {
            Value::Pose(p) => Some(p),
            _ => None,
        }
    }
}
