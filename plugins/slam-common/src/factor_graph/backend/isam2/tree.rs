//! The Bayes tree: cliques of frontal variables, each holding the Gaussian conditional of
//! its frontal variables on its separator and the marginal factor it passed to its parent
//! when it was eliminated (Kaess et al., "iSAM2", IJRR 31(2), 2012, §3: the "cached
//! factor" that stands for the whole subtree when the clique becomes an orphan).
//!
//! Elimination groups consecutive variables into one clique when the next variable is
//! the first of the clique's separator and brings no new variable with it (fundamental
//! supernodes), so a chain of variables sharing a separator is eliminated from one dense
//! matrix instead of passing it on variable by variable. A clique's parent is the clique
//! of its first-eliminated separator variable, so every separator lies on the path to
//! the root (the running intersection property).

use std::collections::{BTreeMap, BTreeSet, HashMap};

use nalgebra::{DMatrix, DVector};

use super::linear::{self, Conditional, InfoFactor};

const NONE: usize = usize::MAX;

#[derive(Debug, Clone)]
pub(crate) struct Clique {
    /// Frontal variables, in elimination order.
    frontals: Vec<usize>,
    /// Separator variables, in elimination order.
    sep: Vec<usize>,
    conditional: Conditional,
    /// The factor on `sep` this clique's elimination produced: its whole subtree's
    /// information about the rest of the graph.
    pub(crate) marginal: InfoFactor,
    parent: usize,
    children: Vec<usize>,
}

/// Cliques in an arena, with each variable's clique.
#[derive(Debug, Clone, Default)]
pub(crate) struct BayesTree {
    cliques: Vec<Option<Clique>>,
    free: Vec<usize>,
    of_var: Vec<usize>,
    roots: BTreeSet<usize>,
}

/// The part of the tree an update removes.
#[derive(Debug, Default)]
pub(crate) struct Top {
    /// Frontal variables of the removed cliques.
    pub(crate) vars: BTreeSet<usize>,
    cliques: Vec<usize>,
    /// Roots of the subtrees left hanging (clique ids).
    pub(crate) orphans: Vec<usize>,
}

/// The result of eliminating a top: its cliques (parent given by a variable), each
/// variable's position in the ordering, and the error no variable explains.
#[derive(Debug)]
pub(crate) struct Eliminated {
    cliques: Vec<(Clique, Option<usize>)>,
    position: HashMap<usize, usize>,
    pub(crate) leftover: f64,
}

impl BayesTree {
    /// Whether the variable has been eliminated into the tree.
    pub(crate) fn contains(&self, v: usize) -> bool {
        self.of_var.get(v).is_some_and(|&c| c != NONE)
    }

    fn clique(&self, id: usize) -> Option<&Clique> {
        self.cliques.get(id)?.as_ref()
    }

    /// An orphan's marginal factor.
    pub(crate) fn marginal(&self, id: usize) -> Option<&InfoFactor> {
        self.clique(id).map(|c| &c.marginal)
    }

    /// The cliques holding `marked` variables with all their ancestors, and the subtrees
    /// hanging below them (their roots, the orphans).
    pub(crate) fn top(&self, marked: &BTreeSet<usize>) -> Top {
        let mut removed = BTreeSet::new();
        for &v in marked {
            let mut at = self.of_var.get(v).copied().unwrap_or(NONE);
            while at != NONE && removed.insert(at) {
                at = self.clique(at).map_or(NONE, |c| c.parent);
            }
        }
        let mut top = Top::default();
        for &r in &removed {
            if let Some(c) = self.clique(r) {
                top.vars.extend(c.frontals.iter().copied());
                top.orphans.extend(
                    c.children
                        .iter()
                        .copied()
                        .filter(|ch| !removed.contains(ch)),
                );
            }
        }
        top.orphans.sort_unstable();
        top.cliques = removed.into_iter().collect();
        top
    }

    /// Drops the `top`'s cliques, adds the re-eliminated ones, and hangs each orphan under
    /// the clique of its separator variable eliminated first; the new cliques' ids.
    pub(crate) fn replace_top(&mut self, top: &Top, new: Eliminated) -> Vec<usize> {
        for &r in &top.cliques {
            if let Some(c) = self.cliques.get_mut(r).and_then(Option::take) {
                for &v in &c.frontals {
                    self.of_var[v] = NONE;
                }
                self.free.push(r);
            }
            self.roots.remove(&r);
        }
        let mut ids = Vec::with_capacity(new.cliques.len());
        let mut parents = Vec::with_capacity(new.cliques.len());
        for (clique, parent_var) in new.cliques {
            let id = match self.free.pop() {
                Some(id) => id,
                None => {
                    self.cliques.push(None);
                    self.cliques.len() - 1
                }
            };
            for &v in &clique.frontals {
                if self.of_var.len() <= v {
                    self.of_var.resize(v + 1, NONE);
                }
                self.of_var[v] = id;
            }
            self.cliques[id] = Some(clique);
            ids.push(id);
            parents.push(parent_var);
        }
        // Parents are new cliques too (a separator lies in the top), so resolve them
        // only now that every new clique has its id.
        for (&id, parent_var) in ids.iter().zip(parents) {
            let parent = parent_var.map_or(NONE, |v| self.of_var[v]);
            self.link(id, parent);
        }
        for &o in &top.orphans {
            let first = self.clique(o).and_then(|c| {
                c.sep
                    .iter()
                    .copied()
                    .min_by_key(|s| new.position.get(s).copied().unwrap_or(NONE))
            });
            let parent = first.map_or(NONE, |v| self.of_var[v]);
            self.link(o, parent);
        }
        ids
    }

    fn link(&mut self, child: usize, parent: usize) {
        if let Some(Some(c)) = self.cliques.get_mut(child) {
            c.parent = parent;
        }
        match self.cliques.get_mut(parent).and_then(Option::as_mut) {
            Some(p) => p.children.push(child),
            None => {
                self.roots.insert(child);
            }
        }
    }

    /// Wildfire back-substitution: re-solves the `new` cliques and, below them, every
    /// clique one of whose separator variables moved by at least `threshold`.
    pub(crate) fn back_substitute(
        &self,
        new: &BTreeSet<usize>,
        deltas: &mut [DVector<f64>],
        threshold: f64,
    ) {
        let mut changed = vec![false; deltas.len()];
        let mut stack: Vec<usize> = self.roots.iter().rev().copied().collect();
        let (mut sep, mut solved) = (DVector::zeros(0), DVector::zeros(0));
        while let Some(id) = stack.pop() {
            let Some(clique) = self.clique(id) else {
                continue;
            };
            if !new.contains(&id) && !clique.sep.iter().any(|&s| changed[s]) {
                continue;
            }
            let sep_dim: usize = clique.sep.iter().map(|&s| deltas[s].len()).sum();
            sep.resize_vertically_mut(sep_dim, 0.0);
            let mut at = 0;
            for &s in &clique.sep {
                let d = &deltas[s];
                sep.rows_mut(at, d.len()).copy_from(d);
                at += d.len();
            }
            clique.conditional.solve_into(&sep, &mut solved);
            let mut at = 0;
            for &f in &clique.frontals {
                let d = &mut deltas[f];
                let len = d.len();
                let mut moved: f64 = 0.0;
                for (old, new_value) in d.iter_mut().zip(solved.rows(at, len).iter()) {
                    moved = moved.max((new_value - *old).abs());
                    *old = *new_value;
                }
                if moved >= threshold || !moved.is_finite() {
                    changed[f] = true;
                }
                at += len;
            }
            stack.extend(clique.children.iter().rev().copied());
        }
    }
}

impl BayesTree {
    /// The covariance of variable `v`'s step (its marginal at the linearisation point),
    /// `dims` giving every variable's dimension; `None` if `v` is not in the tree.
    ///
    /// Top-down along the path from the root to `v`'s clique, as GTSAM's
    /// `BayesTree::marginalFactor` does (covariances from the square-root information
    /// factor: Kaess and Dellaert, "Covariance recovery from a square root information
    /// matrix for data association", Robotics and Autonomous Systems 57(12), 2009): a clique's
    /// conditional `R·δ_f + S·δ_s = d` with unit noise makes its frontals, given the
    /// separator, `N(R⁻¹(d − S·δ_s), (RᵀR)⁻¹)`; with the separator's covariance `Σ_s` (read
    /// from the joint of the parent's frontals and separator, which hold it by the running
    /// intersection property) the joint is `Σ_f = R⁻¹(I + S·Σ_s·Sᵀ)R⁻ᵀ`,
    /// `Σ_fs = −R⁻¹·S·Σ_s`. Each step costs the clique's size cubed; the path is short for
    /// the newest variables, which iSAM2 keeps near the root.
    pub(crate) fn covariance(&self, v: usize, dims: &[usize]) -> Option<DMatrix<f64>> {
        let mut path = Vec::new();
        let mut at = self.of_var.get(v).copied().unwrap_or(NONE);
        while at != NONE {
            path.push(at);
            at = self.clique(at)?.parent;
        }
        path.reverse();
        // The joint covariance of the previous clique's frontals and separator.
        let mut vars: Vec<usize> = Vec::new();
        let mut joint = DMatrix::zeros(0, 0);
        for id in path {
            let c = self.clique(id)?;
            // Where each separator variable's block starts in `joint`, and its width.
            let mut starts = BTreeMap::new();
            let mut n = 0;
            for &u in &vars {
                starts.insert(u, n);
                n += dims[u];
            }
            let sep_at: Vec<(usize, usize)> = c
                .sep
                .iter()
                .map(|u| starts.get(u).map(|&s| (s, dims[*u])))
                .collect::<Option<_>>()?;
            let sep_dim: usize = sep_at.iter().map(|(_, d)| d).sum();
            let mut sigma_s = DMatrix::zeros(sep_dim, sep_dim);
            let mut row = 0;
            for &(r0, rd) in &sep_at {
                let mut col = 0;
                for &(c0, cd) in &sep_at {
                    sigma_s
                        .view_mut((row, col), (rd, cd))
                        .copy_from(&joint.view((r0, c0), (rd, cd)));
                    col += cd;
                }
                row += rd;
            }
            let r = &c.conditional.r;
            let f = r.nrows();
            let mut r_inv = DMatrix::identity(f, f);
            if !r.solve_upper_triangular_mut(&mut r_inv) {
                return None;
            }
            // R⁻¹·S·Σ_s, then Σ_f = R⁻¹R⁻ᵀ + (R⁻¹S)·Σ_s·(R⁻¹S)ᵀ.
            let rs = &r_inv * &c.conditional.s;
            let rs_sigma = &rs * &sigma_s;
            let sigma_f = &r_inv * r_inv.transpose() + &rs_sigma * rs.transpose();
            let mut next = DMatrix::zeros(f + sep_dim, f + sep_dim);
            next.view_mut((0, 0), (f, f)).copy_from(&sigma_f);
            if sep_dim > 0 {
                let cross = -rs_sigma;
                next.view_mut((0, f), (f, sep_dim)).copy_from(&cross);
                next.view_mut((f, 0), (sep_dim, f))
                    .copy_from(&cross.transpose());
                next.view_mut((f, f), (sep_dim, sep_dim))
                    .copy_from(&sigma_s);
            }
            vars = c.frontals.iter().chain(&c.sep).copied().collect();
            joint = next;
        }
        let mut start = 0;
        for &u in &vars {
            if u == v {
                let d = dims[u];
                let block = joint.view((start, start), (d, d)).into_owned();
                // Symmetric by construction up to rounding.
                return Some((block.transpose() + block) * 0.5);
            }
            start += dims[u];
        }
        None
    }
}

/// Eliminates `order` from `inputs` (the linearised factors of the top and the orphans'
/// marginals; `dims` by variable). On failure, a variable that could not be eliminated.
pub(crate) fn eliminate(
    order: &[usize],
    inputs: &[&InfoFactor],
    dims: &[usize],
) -> Result<Eliminated, usize> {
    let position: HashMap<usize, usize> = order.iter().enumerate().map(|(i, &v)| (v, i)).collect();
    let pos = |k: &usize| position.get(k).copied().unwrap_or(NONE);
    /// A factor waiting for its first variable: an input, or the marginal of a new
    /// clique (by its index in `cliques`).
    #[derive(Clone, Copy)]
    enum Pending {
        Input(usize),
        Marginal(usize),
    }
    let mut buckets: Vec<Vec<Pending>> = (0..order.len()).map(|_| Vec::new()).collect();
    let mut leftover = 0.0;
    for (i, f) in inputs.iter().enumerate() {
        match f.keys.iter().map(pos).min() {
            Some(p) if p != NONE => buckets[p].push(Pending::Input(i)),
            _ => leftover += f.constant(),
        }
    }
    let mut cliques: Vec<(Clique, Option<usize>)> = Vec::new();
    let keys_of = |x: &Pending, cliques: &[(Clique, Option<usize>)]| -> Vec<usize> {
        match *x {
            Pending::Input(i) => inputs[i].keys.clone(),
            Pending::Marginal(c) => cliques[c].0.marginal.keys.clone(),
        }
    };
    let mut p = 0;
    while p < order.len() {
        let mut frontals = vec![order[p]];
        let mut pending = std::mem::take(&mut buckets[p]);
        if pending.is_empty() {
            return Err(order[p]);
        }
        let mut keys: BTreeSet<(usize, usize)> = BTreeSet::new();
        for x in &pending {
            keys.extend(keys_of(x, &cliques).into_iter().map(|k| (pos(&k), k)));
        }
        // Grow the clique while the next variable is its first separator variable and
        // its own factors bring no variable the clique does not already have.
        loop {
            let q = p + frontals.len();
            let Some(&u) = order.get(q) else { break };
            let first_sep = keys
                .iter()
                .find(|(_, k)| !frontals.contains(k))
                .map(|&(_, k)| k);
            if first_sep != Some(u) {
                break;
            }
            let inside = buckets[q].iter().all(|x| {
                keys_of(x, &cliques)
                    .iter()
                    .all(|k| keys.contains(&(pos(k), *k)))
            });
            if !inside {
                break;
            }
            frontals.push(u);
            pending.extend(std::mem::take(&mut buckets[q]));
        }
        let all: Vec<usize> = keys.iter().map(|&(_, k)| k).collect();
        let key_dims: Vec<usize> = all.iter().map(|&k| dims[k]).collect();
        let factors: Vec<&InfoFactor> = pending
            .iter()
            .map(|x| match *x {
                Pending::Input(i) => inputs[i],
                Pending::Marginal(c) => &cliques[c].0.marginal,
            })
            .collect();
        let m = linear::combine(&all, &key_dims, &factors);
        let frontal_dim: usize = key_dims[..frontals.len()].iter().sum();
        let (conditional, aug) = linear::eliminate(m, frontal_dim).map_err(|_| frontals[0])?;
        let sep = all[frontals.len()..].to_vec();
        let parent_var = sep.first().copied();
        match parent_var {
            Some(s) => buckets[pos(&s)].push(Pending::Marginal(cliques.len())),
            None => leftover += aug[(0, 0)],
        }
        p += frontals.len();
        cliques.push((
            Clique {
                marginal: InfoFactor {
                    keys: sep.clone(),
                    dims: key_dims[frontals.len()..].to_vec(),
                    aug,
                },
                frontals,
                sep,
                conditional,
                parent: NONE,
                children: Vec::new(),
            },
            parent_var,
        ));
    }
    Ok(Eliminated {
        cliques,
        position,
        leftover,
    })
}
