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

use std::collections::{BTreeMap, BTreeSet};

use ::factrs::containers::{Key, Values};
use nalgebra::Isometry3;

use super::{
    Backend, BackendConfig, BackendError, Factor, FactorId, ImuBias, Scope, UpdateReport, Value,
    Var, convert,
    entry::Entry,
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
