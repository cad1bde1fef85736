//! One update: build the factrs graph and values of a [`Subproblem`], run
//! Levenberg–Marquardt from the current estimate (a warm start), and read back the
//! variables it was allowed to move.

use std::{
    collections::BTreeMap,
    panic::{AssertUnwindSafe, catch_unwind},
};

use ::factrs::{
    containers::FactorBuilder,
    containers::{Graph, Key, Values},
    noise::GaussianNoise,
    optimizers::{LevenMarquardt, OptError, Optimizer},
    residuals::PriorResidual,
    variables::{ImuBias as FBias, SE3, VectorVar3},
};

use super::{
    BackendError, FactorId, UpdateReport, Value, Var, convert, entry::Entry, scope::Subproblem,
};

/// Standard deviation of the priors that hold variables outside the window (rad, m,
/// m/s; rad/s and m/s² for biases). Far below any sensor's, so the window sees them as
/// constants; they are never written back, so held variables do not move at all.
const HELD_SIGMA: f64 = 1e-7;
const HELD_BIAS_SIGMA: f64 = 1e-9;

/// Stop when an iteration lowers the error by less than this fraction of it.
const RELATIVE_TOLERANCE: f64 = 1e-6;

/// A variable's factrs key and current estimate.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Slot {
    pub(crate) key: Key,
    pub(crate) value: Value,
}

/// The moved variables' new estimates and what the update did.
#[derive(Debug)]
pub(crate) struct Solution {
    pub(crate) values: Vec<(Var, Value)>,
    pub(crate) report: UpdateReport,
}

pub(crate) fn solve(
    sub: &Subproblem,
    slots: &BTreeMap<Var, Slot>,
    factors: &BTreeMap<FactorId, Entry>,
    max_iterations: usize,
) -> Result<Solution, BackendError> {
    let mut values = Values::new();
    for var in sub.free.iter().chain(&sub.held) {
        let slot = slots.get(var).ok_or(BackendError::MissingVariable(*var))?;
        insert(&mut values, slot.key, &slot.value);
    }
    // Every key a factor names was inserted just above: `add` refuses factors on unknown
    // variables and variables are never removed, so the fallback key is never used.
    let key = |v: Var| slots.get(&v).map_or(Key(u64::MAX), |s| s.key);
    let mut graph = Graph::with_capacity(sub.factors.len() + sub.held.len());
    for id in &sub.factors {
        if let Some(entry) = factors.get(id) {
            graph.add_factor(entry.build(key, true));
        }
    }
    let user_factors = graph.len();
    for var in &sub.held {
        if let Some(slot) = slots.get(var) {
            graph.add_factor(anchor(slot));
        }
    }
    let error = |g: &Graph, v: &Values| -> f64 {
        2.0 * g.iter().take(user_factors).map(|f| f.error(v)).sum::<f64>()
    };
    let error_before = error(&graph, &values);
    let mut report = UpdateReport {
        variables: sub.free.len(),
        factors: user_factors,
        iterations: 0,
        error_before,
        error_after: error_before,
    };
    if user_factors == 0 || max_iterations == 0 {
        return Ok(Solution {
            values: Vec::new(),
            report,
        });
    }
    // factrs panics when the normal equations are not positive definite (e.g. a graph
    // with no prior, whose gauge is free); that is reported, and the estimate is kept.
    let (values, iterations) = catch_unwind(AssertUnwindSafe(|| {
        optimise(graph.clone(), values, max_iterations)
    }))
    .map_err(|p| BackendError::Solver(panic_message(p.as_ref())))??;
    report.iterations = iterations;
    report.error_after = error(&graph, &values);
    let moved = sub
        .free
        .iter()
        .filter_map(|var| Some((*var, read(&values, slots.get(var)?.key, *var)?)))
        .collect();
    Ok(Solution {
        values: moved,
        report,
    })
}

/// Levenberg–Marquardt, stepping by hand: factrs's `optimize` drops the values when a
/// step fails to lower the error (which at a minimum just means convergence).
fn optimise(
    graph: Graph,
    mut values: Values,
    max_iterations: usize,
) -> Result<(Values, usize), BackendError> {
    let mut opt = LevenMarquardt::new_default(graph);
    opt.init(&values);
    let mut err = opt.error(&values);
    let mut iterations = 0;
    if err <= f64::EPSILON {
        // Already satisfied: LM would only raise its damping until it gives up.
        return Ok((values, 0));
    }
    for i in 1..=max_iterations {
        let (next, _) = match opt.step(values.clone(), i) {
            Ok(step) => step,
            Err(OptError::FailedToStep) => break,
            Err(e) => return Err(BackendError::Solver(format!("{e:?}"))),
        };
        let next_err = opt.error(&next);
        values = next;
        iterations = i;
        let decrease = err - next_err;
        err = next_err;
        if decrease <= RELATIVE_TOLERANCE * err.max(f64::MIN_POSITIVE) {
            break;
        }
    }
    Ok((values, iterations))
}

/// A prior holding a variable at its current estimate.
fn anchor(slot: &Slot) -> ::factrs::containers::Factor {
    match &slot.value {
        Value::Pose(p) => {
            FactorBuilder::new1_unchecked(PriorResidual::new(convert::se3_from_iso(p)), slot.key)
                .noise(GaussianNoise::<6>::from_scalar_sigma(HELD_SIGMA))
                .build()
        }
        Value::Velocity(v) => {
            FactorBuilder::new1_unchecked(PriorResidual::new(convert::fvel(v)), slot.key)
                .noise(GaussianNoise::<3>::from_scalar_sigma(HELD_SIGMA))
                .build()
        }
        Value::Bias(b) => {
            FactorBuilder::new1_unchecked(PriorResidual::new(convert::fbias(b)), slot.key)
                .noise(GaussianNoise::<6>::from_scalar_sigma(HELD_BIAS_SIGMA))
                .build()
        }
    }
}

pub(crate) fn insert(values: &mut Values, key: Key, value: &Value) {
    match value {
        Value::Pose(p) => values.insert_unchecked(key, convert::se3_from_iso(p)),
        Value::Velocity(v) => values.insert_unchecked(key, convert::fvel(v)),
        Value::Bias(b) => values.insert_unchecked(key, convert::fbias(b)),
    };
}

fn read(values: &Values, key: Key, var: Var) -> Option<Value> {
    Some(match var {
        Var::Pose(_) => Value::Pose(convert::iso_from_se3(values.get_unchecked::<_, SE3>(key)?)),
        Var::Velocity(_) => Value::Velocity(values.get_unchecked::<_, VectorVar3>(key)?.0),
        Var::Bias(_) => Value::Bias(convert::bias_from_f(values.get_unchecked::<_, FBias>(key)?)),
    })
}

fn panic_message(p: &(dyn std::any::Any + Send)) -> String {
    p.downcast_ref::<&str>()
        .map(|s| s.to_string())
        .or_else(|| p.downcast_ref::<String>().cloned())
        .unwrap_or_else(|| "factrs panicked".to_string())
}
