//! [`FactrsBackend`]: the shared backend on the `factrs` crate.
//!
//! It keeps its own graph (variables with their current estimates, factors by id, and an
//! index from keyframe key to the factors touching it) and builds a factrs problem for
//! each update, because factrs graphs cannot remove a factor and are not `Send`. Each
//! update solves a nonlinear least-squares problem over the factors in scope with
//! Levenberg–Marquardt (Dellaert and Kaess, "Factor Graphs for Robot Perception", 2017),
//! warm-started from the current estimate. [`Scope::Incremental`] solves only the newest
//! `window` keyframes (the `scope` module explains how this approximates iSAM2);
//! [`Scope::Full`] solves everything.
//!
//! [`Backend::marginal_covariance`] linearises every factor at the current estimate and
//! eliminates the whole system with the pose last (the native iSAM2's elimination, module
//! `isam2`), reading its covariance from the root clique: the marginal of the full graph's
//! information matrix. Not the window's alone: there the poses older than the window are
//! held fixed, which would give the covariance *conditional* on them — one that stops
//! growing after `window` keyframes of odometry, where LIO-SAM's `poseCovThreshold` needs
//! it to keep growing. The cost is a pass over the graph per call.

use std::collections::{BTreeMap, BTreeSet};

use ::factrs::containers::{Key, Values};
use nalgebra::{Isometry3, Matrix6};

use super::{
    Backend, BackendConfig, BackendError, Factor, FactorId, ImuBias, PoseCovariance, Scope,
    UpdateReport, Value, Var, convert,
    entry::Entry,
    isam2,
    scope::{self, keyframe},
    solve::{self, Slot},
};

/// The factor-graph backend on factrs; how it works is in this file's module documentation.
#[derive(Debug, Clone)]
pub struct FactrsBackend {
    window: usize,
    max_iterations: usize,
    vars: BTreeMap<Var, Slot>,
    factors: BTreeMap<FactorId, Entry>,
    /// Factors touching any variable of a keyframe, by keyframe key.
    by_keyframe: BTreeMap<u64, BTreeSet<FactorId>>,
    next_factor: u64,
}

impl FactrsBackend {
    /// An empty graph with the configuration's window and iteration limit (its name is
    /// not checked here; [`from_config`](super::from_config) does that).
    pub fn new(config: &BackendConfig) -> Self {
        Self {
            window: config.window,
            max_iterations: config.max_iterations,
            vars: BTreeMap::new(),
            factors: BTreeMap::new(),
            by_keyframe: BTreeMap::new(),
            next_factor: 0,
        }
    }

    fn bias(&self, key: u64) -> Option<ImuBias> {
        match self.vars.get(&Var::Bias(key))?.value {
            Value::Bias(b) => Some(b),
            _ => None,
        }
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

pub(crate) fn check_value(var: Var, value: &Value) -> Result<(), BackendError> {
    if !same_kind(var, value) {
        return Err(BackendError::Invalid(format!(
            "{var:?} cannot hold {value:?}"
        )));
    }
    convert::check_value(value)
}

impl Backend for FactrsBackend {
    fn insert(&mut self, var: Var, initial: Value) -> Result<(), BackendError> {
        check_value(var, &initial)?;
        if self.vars.contains_key(&var) {
            return Err(BackendError::Duplicate(var));
        }
        // factrs keys are dense indices: any u64 key of ours maps to a distinct one.
        let key = Key(self.vars.len() as u64);
        self.vars.insert(
            var,
            Slot {
                key,
                value: initial,
            },
        );
        Ok(())
    }

    fn add(&mut self, factor: Factor) -> Result<FactorId, BackendError> {
        let entry = Entry::new(factor, |k| self.bias(k))?;
        if let Some(missing) = entry.vars().iter().find(|v| !self.vars.contains_key(v)) {
            return Err(BackendError::MissingVariable(*missing));
        }
        let id = FactorId(self.next_factor);
        self.next_factor += 1;
        for &var in entry.vars() {
            self.by_keyframe
                .entry(keyframe(var))
                .or_default()
                .insert(id);
        }
        self.factors.insert(id, entry);
        Ok(id)
    }

    fn remove(&mut self, id: FactorId) -> bool {
        let Some(entry) = self.factors.remove(&id) else {
            return false;
        };
        for &var in entry.vars() {
            if let Some(ids) = self.by_keyframe.get_mut(&keyframe(var)) {
                ids.remove(&id);
            }
        }
        true
    }

    fn update(&mut self, scope: Scope) -> Result<UpdateReport, BackendError> {
        let sub = match scope {
            Scope::Full => scope::full(&self.factors),
            Scope::Incremental => scope::window(
                self.pose_keys_desc(),
                self.window,
                &self.by_keyframe,
                &self.factors,
            ),
        };
        let solution = solve::solve(&sub, &self.vars, &self.factors, self.max_iterations)?;
        for (var, value) in solution.values {
            if let Some(slot) = self.vars.get_mut(&var) {
                slot.value = value;
            }
        }
        Ok(solution.report)
    }

    fn value(&self, var: Var) -> Option<Value> {
        self.vars.get(&var).map(|s| s.value)
    }

    fn set_value(&mut self, var: Var, value: Value) -> Result<(), BackendError> {
        check_value(var, &value)?;
        let slot = self
            .vars
            .get_mut(&var)
            .ok_or(BackendError::MissingVariable(var))?;
        slot.value = value;
        Ok(())
    }

    fn factor_error(&self, id: FactorId) -> Option<f64> {
        let entry = self.factors.get(&id)?;
        let mut values = Values::new();
        for var in entry.vars() {
            let slot = self.vars.get(var)?;
            solve::insert(&mut values, slot.key, &slot.value);
        }
        let key = |v: Var| self.vars.get(&v).map_or(Key(u64::MAX), |s| s.key);
        // Without its kernel factrs's error is ½‖r‖² of the whitened residual r.
        let half_sq = entry.build(key, false).error(&values);
        Some((2.0 * half_sq).sqrt())
    }

    fn pose_keys(&self) -> Vec<u64> {
        self.pose_range().map(|(v, _)| keyframe(*v)).collect()
    }

    /// Every factor linearised at the current estimate (robust ones reweighted there, as
    /// the solver does), eliminated with the pose last: see the module documentation.
    fn marginal_covariance(&self, key: u64) -> Result<PoseCovariance, BackendError> {
        let var = Var::Pose(key);
        let target = self
            .vars
            .get(&var)
            .ok_or(BackendError::MissingVariable(var))?;
        let Value::Pose(world_from_body) = target.value else {
            return Err(BackendError::MissingVariable(var));
        };
        // factrs keys are the dense indices `insert` gave.
        let mut dims = vec![0; self.vars.len()];
        let mut values = Values::new();
        for (v, slot) in &self.vars {
            dims[slot.key.0 as usize] = match v {
                Var::Pose(_) | Var::Bias(_) => 6,
                Var::Velocity(_) => 3,
            };
            solve::insert(&mut values, slot.key, &slot.value);
        }
        let key_of = |v: Var| self.vars.get(&v).map_or(Key(u64::MAX), |s| s.key);
        let mut linear = Vec::with_capacity(self.factors.len());
        for entry in self.factors.values() {
            let factor = entry.build(key_of, true);
            linear.push(isam2::linearise(&factor, &values, &dims).ok_or_else(|| {
                BackendError::Solver(format!(
                    "a factor on {:?} linearised to non-finite values",
                    entry.vars()
                ))
            })?);
        }
        let cov = isam2::covariance_of(&linear, &dims, target.key.0 as usize).map_err(|i| {
            let unconstrained = self
                .vars
                .iter()
                .find(|(_, s)| s.key.0 as usize == i)
                .map_or(var, |(v, _)| *v);
            BackendError::Solver(format!(
                "no marginal of pose {key}: {unconstrained:?} is not constrained (no prior?)"
            ))
        })?;
        Ok(PoseCovariance {
            tangent: Matrix6::from_fn(|r, c| cov[(r, c)]),
            world_from_body,
        })
    }

    fn pose(&self, key: u64) -> Option<Isometry3<f64>> {
        match self.vars.get(&Var::Pose(key))?.value {
            Value::Pose(p) => Some(p),
            _ => None,
        }
    }
}

impl FactrsBackend {
    fn pose_range(&self) -> impl DoubleEndedIterator<Item = (&Var, &Slot)> {
        self.vars.range(Var::Pose(0)..=Var::Pose(u64::MAX))
    }

    fn pose_keys_desc(&self) -> impl Iterator<Item = u64> + '_ {
        self.pose_range().rev().map(|(v, _)| keyframe(*v))
    }
}
