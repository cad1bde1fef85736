//! The elimination ordering of the part of the graph an update re-eliminates: minimum
//! degree with two constraint groups, the variables of the newest factors last.
//!
//! iSAM2 orders the variables it re-eliminates with constrained COLAMD so that the newest
//! variables end up near the root, where the next update will find them (Kaess et al.,
//! "iSAM2", IJRR 31(2), 2012, §5.2). This is the same idea on the variables' adjacency
//! graph: an exact minimum-degree ordering (George and Liu, "The evolution of the minimum
//! degree ordering algorithm", SIAM Review 31(1), 1989) on the explicit elimination graph,
//! eliminating group 0 before group 1; ties go to the lower variable index, so the
//! ordering is deterministic.

use std::cmp::Reverse;
use std::collections::{BTreeSet, BinaryHeap, HashMap};

/// Orders `vars`; `cliques` are the key sets of the factors among them (every key in
/// `vars`), `last` the variables that must come after all others.
pub(crate) fn constrained_min_degree(
    vars: &[usize],
    cliques: impl IntoIterator<Item = impl AsRef<[usize]>>,
    last: &BTreeSet<usize>,
) -> Vec<usize> {
    let local: HashMap<usize, u32> = vars
        .iter()
        .enumerate()
        .map(|(i, &v)| (v, i as u32))
        .collect();
    let mut adjacency: Vec<BTreeSet<u32>> = vec![BTreeSet::new(); vars.len()];
    for clique in cliques {
        let ids: Vec<u32> = clique
            .as_ref()
            .iter()
            .filter_map(|k| local.get(k).copied())
            .collect();
        for &a in &ids {
            for &b in &ids {
                if a != b {
                    adjacency[a as usize].insert(b);
                }
            }
        }
    }
    let group = |i: u32| u8::from(last.contains(&vars[i as usize]));
    let mut heap: BinaryHeap<Reverse<(u8, usize, usize, u32)>> = (0..vars.len() as u32)
        .map(|i| Reverse((group(i), adjacency[i as usize].len(), vars[i as usize], i)))
        .collect();
    let mut done = vec![false; vars.len()];
    let mut order = Vec::with_capacity(vars.len());
    while let Some(Reverse((_, degree, _, i))) = heap.pop() {
        let iu = i as usize;
        if done[iu] || degree != adjacency[iu].len() {
            continue;
        }
        done[iu] = true;
        order.push(vars[iu]);
        let neighbours = std::mem::take(&mut adjacency[iu]);
        for &a in &neighbours {
            let adj = &mut adjacency[a as usize];
            adj.remove(&i);
            adj.extend(neighbours.iter().copied().filter(|&b| b != a));
            heap.push(Reverse((group(a), adj.len(), vars[a as usize], a)));
        }
    }
    order
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_chain_is_ordered_from_its_ends_and_constrained_variables_come_last() {
        // Guards the two properties iSAM2 relies on: no fill on a chain (leaves first)
        // and the constrained group at the end.
        let chain: Vec<[usize; 2]> = (0..5).map(|i| [i, i + 1]).collect();
        let vars: Vec<usize> = (0..6).collect();
        let order = constrained_min_degree(&vars, &chain, &BTreeSet::new());
        assert_eq!(order.len(), 6);
        assert_eq!(
            order[0], 0,
            "a leaf (degree 1, lowest index) first: {order:?}"
        );
        let last: BTreeSet<usize> = [2].into();
        let order = constrained_min_degree(&vars, &chain, &last);
        assert_eq!(*order.last().expect("non-empty"), 2, "{order:?}");
    }
}
