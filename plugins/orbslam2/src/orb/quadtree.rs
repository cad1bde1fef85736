//! ORB-SLAM2's keypoint distribution (`ORBextractor::DistributeOctTree`): a level's area
//! split as a quadtree until there are as many nodes as keypoints wanted, the strongest
//! corner of each node kept.

use super::Corner;

/// A quadtree node: a rectangle of the level and the corners in it, a contiguous run
/// `order[start..end]` of corner indices.
#[derive(Debug, Clone, Copy)]
pub(super) struct Node {
    pub(super) x0: f32,
    pub(super) y0: f32,
    pub(super) x1: f32,
    pub(super) y1: f32,
    pub(super) start: usize,
    pub(super) end: usize,
}

impl Node {
    pub(super) fn len(&self) -> usize {
        self.end - self.start
    }

    /// Holds two corners or more and can still separate them (corners sit on whole pixels,
    /// so a node holding two is at least 1 px wide or high).
    pub(super) fn can_split(&self) -> bool {
        self.len() > 1 && (self.x1 - self.x0 > 0.5 || self.y1 - self.y0 > 0.5)
    }
}

/// ORB-SLAM2's keypoint distribution, with buffers reused across calls.
#[derive(Debug, Default)]
pub(super) struct QuadTree {
    pub(super) order: Vec<u32>,
    pub(super) scratch: Vec<u32>,
    pub(super) nodes: Vec<Node>,
    pub(super) next: Vec<Node>,
    pub(super) largest: Vec<usize>,
}

impl QuadTree {
    /// Indices of the corners kept: the strongest of each node once the area
    /// `[x0, y0, x1, y1]` is split into `target` nodes (or as many as can be), in node order.
    pub(super) fn distribute(
        &mut self,
        corners: &[Corner],
        area: [f32; 4],
        target: usize,
    ) -> Vec<usize> {
        if corners.is_empty() || target == 0 {
            return Vec::new();
        }
        self.initial_nodes(corners, area);
        while self.nodes.len() < target {
            self.next.clear();
            let mut splittable = 0;
            let mut split_any = false;
            for i in 0..self.nodes.len() {
                let node = self.nodes[i];
                if !node.can_split() {
                    self.next.push(node);
                    continue;
                }
                split_any = true;
                for child in self.split(&node, corners) {
                    if child.len() > 0 {
                        splittable += usize::from(child.can_split());
                        self.next.push(child);
                    }
                }
            }
            std::mem::swap(&mut self.nodes, &mut self.next);
            if self.nodes.len() >= target || !split_any || splittable == 0 {
                break;
            }
            if self.nodes.len() + 3 * splittable > target {
                self.split_largest_until(corners, target);
                break;
            }
        }

        self.nodes
            .iter()
            .map(|n| {
                let mut best = self.order[n.start] as usize;
                for &i in &self.order[n.start + 1..n.end] {
                    if corners[i as usize].score > corners[best].score {
                        best = i as usize;
                    }
                }
                best
            })
            .collect()
    }

    /// The area cut into `round(width / height)` (at least 1) columns, empty ones dropped.
    pub(super) fn initial_nodes(&mut self, corners: &[Corner], [x0, y0, x1, y1]: [f32; 4]) {
        let n = ((x1 - x0) / (y1 - y0)).round().max(1.0) as usize;
        let w = (x1 - x0) / n as f32;
        let column = |c: &Corner| (((c.x as f32 - x0) / w) as usize).min(n - 1);
        let mut counts = vec![0usize; n + 1];
        for c in corners {
            counts[column(c) + 1] += 1;
        }
        for i in 1..=n {
            counts[i] += counts[i - 1];
        }
        self.order.clear();
        self.order.resize(corners.len(), 0);
        let mut fill = counts.clone();
        for (i, c) in corners.iter().enumerate() {
            let k = column(c);
            self.order[fill[k]] = i as u32;
            fill[k] += 1;
        }
        self.nodes.clear();
        for k in 0..n {
            if counts[k + 1] > counts[k] {
                self.nodes.push(Node {
                    x0: x0 + k as f32 * w,
                    y0,
                    x1: if k + 1 == n {
                        x1
                    } else {
                        x0 + (k + 1) as f32 * w
                    },
                    y1,
                    start: counts[k],
                    end: counts[k + 1],
                });
            }
        }
    }

    /// Splits nodes, the most populated first (ties in node order), until there are
    /// `target` nodes or none can split.
    pub(super) fn split_largest_until(&mut self, corners: &[Corner], target: usize) {
        loop {
            self.largest.clear();
            self.largest
                .extend((0..self.nodes.len()).filter(|&i| self.nodes[i].can_split()));
            if self.largest.is_empty() {
                return;
            }
            let nodes = &self.nodes;
            self.largest
                .sort_by_key(|&i| std::cmp::Reverse(nodes[i].len()));
            for k in 0..self.largest.len() {
                let i = self.largest[k];
                let node = self.nodes[i];
                let mut first = true;
                for child in self.split(&node, corners) {
                    if child.len() == 0 {
                        continue;
                    }
                    if first {
                        self.nodes[i] = child;
                        first = false;
                    } else {
                        self.nodes.push(child);
                    }
                }
                if self.nodes.len() >= target {
                    return;
                }
            }
        }
    }

    /// The four quadrants of `node` (top-left, top-right, bottom-left, bottom-right), its
    /// run of `order` regrouped by quadrant, keeping the corners' relative order.
    pub(super) fn split(&mut self, node: &Node, corners: &[Corner]) -> [Node; 4] {
        let mx = 0.5 * (node.x0 + node.x1);
        let my = 0.5 * (node.y0 + node.y1);
        let quadrant = |i: u32| {
            let c = &corners[i as usize];
            usize::from(c.x as f32 >= mx) + 2 * usize::from(c.y as f32 >= my)
        };
        let run = &mut self.order[node.start..node.end];
        let mut counts = [0usize; 4];
        for &i in run.iter() {
            counts[quadrant(i)] += 1;
        }
        let mut fill = [
            0,
            counts[0],
            counts[0] + counts[1],
            counts[0] + counts[1] + counts[2],
        ];
        let starts = fill;
        self.scratch.clear();
        self.scratch.resize(run.len(), 0);
        for &i in run.iter() {
            let q = quadrant(i);
            self.scratch[fill[q]] = i;
            fill[q] += 1;
        }
        run.copy_from_slice(&self.scratch);
        let rect = |q: usize| {
            let (x0, x1) = if q % 2 == 0 {
                (node.x0, mx)
            } else {
                (mx, node.x1)
            };
            let (y0, y1) = if q < 2 { (node.y0, my) } else { (my, node.y1) };
            Node {
                x0,
                y0,
                x1,
                y1,
                start: node.start + starts[q],
                end: node.start + starts[q] + counts[q],
            }
        };
        [rect(0), rect(1), rect(2), rect(3)]
    }
}
