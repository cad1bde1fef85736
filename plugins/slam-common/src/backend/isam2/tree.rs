//! The Bayes tree: one clique per eliminated variable, holding its Gaussian conditional on
//! its separator and the marginal factor it passed to its parent when it was eliminated
//! (Kaess et al., "iSAM2", IJRR 31(2), 2012, §3: the "cached factor" that stands for the
//! whole subtree when the clique becomes an orphan).
//!
//! A clique's parent is the clique of its first-eliminated separator variable, so every
//! separator lies on the path to the root (the running intersection property).

use std::collections::{BTreeMap, BTreeSet, HashMap};

use nalgebra::DVector;

use super::linear::{self, Conditional, InfoFactor};

#[derive(Debug, Clone)]
pub(crate) struct Clique {
    /// Separator variables, in elimination order.
    pub(crate) sep: Vec<usize>,
    pub(crate) conditional: Conditional,
    /// The factor on `sep` this clique's elimination produced: its whole subtree's
    /// information about the rest of the graph.
    pub(crate) marginal: InfoFactor,
    parent: Option<usize>,
    children: Vec<usize>,
}

/// Cliques by frontal variable.
#[derive(Debug, Clone, Default)]
pub(crate) struct BayesTree {
    cliques: Vec<Option<Clique>>,
    roots: BTreeSet<usize>,
}

/// The result of eliminating a top: its cliques (parents set, children not yet), each
/// variable's position in the ordering, and the error no variable explains.
#[derive(Debug)]
pub(crate) struct Eliminated {
    pub(crate) cliques: BTreeMap<usize, Clique>,
    pub(crate) position: HashMap<usize, usize>,
    pub(crate) leftover: f64,
}

impl BayesTree {
    pub(crate) fn contains(&self, v: usize) -> bool {
        matches!(self.cliques.get(v), Some(Some(_)))
    }

    pub(crate) fn clique(&self, v: usize) -> Option<&Clique> {
        self.cliques.get(v)?.as_ref()
    }

    /// The cliques of `marked` variables with all their ancestors, and the subtrees
    /// hanging below them (their roots, the orphans).
    pub(crate) fn top(&self, marked: &BTreeSet<usize>) -> (BTreeSet<usize>, Vec<usize>) {
        let mut removed = BTreeSet::new();
        for &v in marked {
            let mut at = Some(v);
            while let Some(c) = at {
                let Some(clique) = self.clique(c) else {
                    break;
                };
                if !removed.insert(c) {
                    break;
                }
                at = clique.parent;
            }
        }
        let mut orphans = Vec::new();
        for &r in &removed {
            if let Some(clique) = self.clique(r) {
                orphans.extend(
                    clique
                        .children
                        .iter()
                        .copied()
                        .filter(|c| !removed.contains(c)),
                );
            }
        }
        orphans.sort_unstable();
        (removed, orphans)
    }

    /// Drops the `removed` cliques, adds the re-eliminated ones, and hangs each orphan
    /// under the clique of its separator variable eliminated first.
    pub(crate) fn replace_top(
        &mut self,
        removed: &BTreeSet<usize>,
        new: BTreeMap<usize, Clique>,
        orphans: &[usize],
        position: &HashMap<usize, usize>,
    ) {
        for &r in removed {
            if let Some(slot) = self.cliques.get_mut(r) {
                *slot = None;
            }
            self.roots.remove(&r);
        }
        let edges: Vec<(usize, Option<usize>)> = new.iter().map(|(&v, c)| (v, c.parent)).collect();
        for (v, clique) in new {
            if self.cliques.len() <= v {
                self.cliques.resize(v + 1, None);
            }
            self.cliques[v] = Some(clique);
        }
        for &o in orphans {
            let parent = self.clique(o).and_then(|c| {
                c.sep
                    .iter()
                    .copied()
                    .min_by_key(|s| position.get(s).copied().unwrap_or(usize::MAX))
            });
            if let Some(Some(c)) = self.cliques.get_mut(o) {
                c.parent = parent;
            }
            self.link(o, parent);
        }
        for (v, parent) in edges {
            self.link(v, parent);
        }
    }

    fn link(&mut self, child: usize, parent: Option<usize>) {
        match parent.and_then(|p| self.cliques.get_mut(p)?.as_mut()) {
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
        while let Some(c) = stack.pop() {
            let Some(clique) = self.clique(c) else {
                continue;
            };
            if !new.contains(&c) && !clique.sep.iter().any(|&s| changed[s]) {
                continue;
            }
            let sep_dim: usize = clique.sep.iter().map(|&s| deltas[s].len()).sum();
            let mut sep = DVector::zeros(sep_dim);
            let mut at = 0;
            for &s in &clique.sep {
                let d = &deltas[s];
                sep.rows_mut(at, d.len()).copy_from(d);
                at += d.len();
            }
            let solved = clique.conditional.solve(&sep);
            let moved = if solved.len() == deltas[c].len() {
                (&solved - &deltas[c]).amax()
            } else {
                f64::INFINITY
            };
            if moved >= threshold {
                changed[c] = true;
            }
            deltas[c] = solved;
            stack.extend(clique.children.iter().rev().copied());
        }
    }
}

/// Eliminates `order` from `inputs` (the linearised factors of the top and the orphans'
/// marginals; `dims` by variable). On failure, the variable that could not be eliminated.
pub(crate) fn eliminate(
    order: &[usize],
    inputs: &[&InfoFactor],
    dims: &[usize],
) -> Result<Eliminated, usize> {
    let position: HashMap<usize, usize> = order.iter().enumerate().map(|(i, &v)| (v, i)).collect();
    let first = |keys: &[usize]| keys.iter().filter_map(|k| position.get(k)).min().copied();
    /// A factor waiting for its first variable: an input or a new clique's marginal.
    enum Pending {
        Input(usize),
        Marginal(usize),
    }
    let mut buckets: Vec<Vec<Pending>> = (0..order.len()).map(|_| Vec::new()).collect();
    let mut leftover = 0.0;
    for (i, f) in inputs.iter().enumerate() {
        match first(&f.keys) {
            Some(p) => buckets[p].push(Pending::Input(i)),
            None => leftover += f.constant(),
        }
    }
    let mut cliques: BTreeMap<usize, Clique> = BTreeMap::new();
    for (p, &v) in order.iter().enumerate() {
        let pending = std::mem::take(&mut buckets[p]);
        if pending.is_empty() {
            return Err(v);
        }
        let factors: Vec<&InfoFactor> = pending
            .iter()
            .filter_map(|x| match x {
                Pending::Input(i) => Some(inputs[*i]),
                Pending::Marginal(c) => cliques.get(c).map(|c| &c.marginal),
            })
            .collect();
        let mut keys: Vec<usize> = factors
            .iter()
            .flat_map(|f| f.keys.iter().copied())
            .collect();
        keys.sort_unstable_by_key(|k| position.get(k).copied().unwrap_or(usize::MAX));
        keys.dedup();
        let key_dims: Vec<usize> = keys.iter().map(|&k| dims[k]).collect();
        let m = linear::combine(&keys, &key_dims, &factors);
        let (conditional, aug) = linear::eliminate(&m, key_dims[0]).map_err(|_| v)?;
        let sep = keys[1..].to_vec();
        let parent = sep.first().copied();
        if let Some(&s) = sep.first() {
            buckets[position[&s]].push(Pending::Marginal(v));
        } else {
            leftover += aug[(0, 0)];
        }
        cliques.insert(
            v,
            Clique {
                marginal: InfoFactor {
                    keys: sep.clone(),
                    dims: key_dims[1..].to_vec(),
                    aug,
                },
                sep,
                conditional,
                parent,
                children: Vec::new(),
            },
        );
    }
    Ok(Eliminated {
        cliques,
        position,
        leftover,
    })
}
