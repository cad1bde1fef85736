//! Binary tree to wide tree: each wide node takes the two children of a binary node and keeps
//! opening the child of largest surface area until it has [`WIDTH`] (as in Embree's BVH4/BVH8
//! builders), so the tree has about a third of the levels and each level's boxes are tested
//! at once.

use super::node::{Node, NodePair, WIDTH, WideNode};

/// The wide nodes in depth-first order (root first) and the depth of the wide tree
/// (1 for a root alone).
pub(super) fn collapse(root: &Node, pairs: &[NodePair]) -> (Vec<WideNode>, usize) {
    let mut nodes = Vec::with_capacity(pairs.len() / 2 + 1);
    if root.count > 0 {
        // A leaf alone: one wide node with one lane used.
        let mut wide = WideNode::EMPTY;
        wide.set(0, root, root.first);
        nodes.push(wide);
        return (nodes, 1);
    }
    let depth = emit(root, pairs, &mut nodes);
    (nodes, depth)
}

/// Appends the wide node for the binary interior node `node` and its subtree; returns the
/// subtree's depth.
fn emit(node: &Node, pairs: &[NodePair], out: &mut Vec<WideNode>) -> usize {
    let mut kids: Vec<Node> = pairs[node.first as usize].0.to_vec();
    while kids.len() < WIDTH {
        let widest = kids.iter().enumerate().filter(|(_, k)| k.count == 0).fold(
            None,
            |best: Option<(usize, f32)>, (i, k)| {
                let a = k.half_area();
                if best.is_none_or(|(_, b)| a > b) {
                    Some((i, a))
                } else {
                    best
                }
            },
        );
        let Some((i, _)) = widest else { break };
        let [a, b] = pairs[kids[i].first as usize].0;
        kids[i] = a;
        kids.insert(i + 1, b);
    }
    let index = out.len();
    out.push(WideNode::EMPTY);
    let mut wide = WideNode::EMPTY;
    let mut depth = 1;
    for (lane, kid) in kids.iter().enumerate() {
        if kid.count > 0 {
            wide.set(lane, kid, kid.first);
        } else {
            let child = u32::try_from(out.len()).expect("node count fits u32");
            depth = depth.max(1 + emit(kid, pairs, out));
            wide.set(lane, kid, child);
        }
    }
    out[index] = wide;
    depth
}
