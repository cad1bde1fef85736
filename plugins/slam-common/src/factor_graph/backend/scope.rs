//! Which part of the graph an update optimises.
//!
//! Without iSAM2's Bayes tree (Kaess et al., "iSAM2: Incremental Smoothing and Mapping
//! Using the Bayes Tree", IJRR 31(2), 2012), which relinearises and re-solves only the
//! variables a new measurement affects, the incremental update approximates it with a
//! sliding window: it moves the variables of the newest `window` keyframes (every kind of
//! variable whose key is at least the window's oldest pose key) and re-solves only the
//! factors touching them. Variables outside the window that those factors also touch are
//! *held*: they enter the problem anchored at their current estimate by a very tight
//! prior and are not written back, so they stay exactly where they were. The work is
//! bounded by the window and the factors per keyframe, not by the graph's size.

use std::collections::{BTreeMap, BTreeSet};

use super::{FactorId, Var, entry::Entry};

/// The variables and factors of one update.
#[derive(Debug, Default)]
pub(crate) struct Subproblem {
    /// Variables the solver moves (only those some factor in scope touches).
    pub(crate) free: BTreeSet<Var>,
    /// Variables outside the window that factors in scope touch: held fixed.
    pub(crate) held: BTreeSet<Var>,
    pub(crate) factors: Vec<FactorId>,
}

/// Everything: every factor, and every variable a factor touches.
pub(crate) fn full(factors: &BTreeMap<FactorId, Entry>) -> Subproblem {
    let mut sub = Subproblem::default();
    for (id, entry) in factors {
        sub.factors.push(*id);
        sub.free.extend(entry.vars().iter().copied());
    }
    sub
}

/// The newest `window` keyframes; `by_keyframe` lists the factors touching any variable
/// with a given key.
pub(crate) fn window(
    pose_keys_desc: impl Iterator<Item = u64>,
    window: usize,
    by_keyframe: &BTreeMap<u64, BTreeSet<FactorId>>,
    factors: &BTreeMap<FactorId, Entry>,
) -> Subproblem {
    let mut sub = Subproblem::default();
    let Some(oldest) = pose_keys_desc.take(window).last() else {
        return sub;
    };
    let ids: BTreeSet<FactorId> = by_keyframe
        .range(oldest..)
        .flat_map(|(_, ids)| ids.iter().copied())
        .collect();
    for id in ids {
        let Some(entry) = factors.get(&id) else {
            continue;
        };
        sub.factors.push(id);
        for &var in entry.vars() {
            if keyframe(var) >= oldest {
                sub.free.insert(var);
            } else {
                sub.held.insert(var);
            }
        }
    }
    sub
}

/// The key a variable shares with the other variables of its keyframe.
pub(crate) fn keyframe(var: Var) -> u64 {
    match var {
        Var::Pose(k) | Var::Velocity(k) | Var::Bias(k) => k,
    }
}
