//! Descriptor matching: nearest neighbour by Hamming distance with the nearest-neighbour
//! distance ratio test (Lowe, IJCV 2004), optionally only within a window around where a
//! motion guess projects each query (RTAB-Map's `Vis/CorGuessWinSize`), and one-to-one.

use crate::features::{Descriptor, hamming};

/// `query` matched to `train`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Match {
    pub query: usize,
    pub train: usize,
    pub distance: u32,
}

/// Train features bucketed by pixel so that a window query visits only nearby cells.
#[derive(Debug)]
pub struct PixelGrid {
    cell_px: f32,
    cols: usize,
    rows: usize,
    cells: Vec<Vec<usize>>,
}

impl PixelGrid {
    pub fn new(pixels: &[[f32; 2]], width: usize, height: usize, cell_px: f32) -> Self {
        let cell_px = cell_px.max(8.0);
        let cols = (width as f32 / cell_px).ceil().max(1.0) as usize;
        let rows = (height as f32 / cell_px).ceil().max(1.0) as usize;
        let mut cells = vec![Vec::new(); cols * rows];
        for (i, p) in pixels.iter().enumerate() {
            let c = ((p[0] / cell_px) as usize).min(cols - 1);
            let r = ((p[1] / cell_px) as usize).min(rows - 1);
            cells[r * cols + c].push(i);
        }
        Self {
            cell_px,
            cols,
            rows,
            cells,
        }
    }

    /// Indices of train features in the cells touching the square of half-side `radius`
    /// around `center` (a superset of the disc; callers check the distance).
    fn around(&self, center: [f32; 2], radius: f32, out: &mut Vec<usize>) {
        out.clear();
        let lo = |v: f32| ((v - radius) / self.cell_px).floor().max(0.0) as usize;
        let hi = |v: f32, n: usize| {
            (((v + radius) / self.cell_px).floor() as isize).clamp(-1, n as isize - 1)
        };
        let (c0, r0) = (lo(center[0]), lo(center[1]));
        let (c1, r1) = (hi(center[0], self.cols), hi(center[1], self.rows));
        if c1 < 0 || r1 < 0 {
            return;
        }
        for r in r0..=r1 as usize {
            for c in c0..=c1 as usize {
                out.extend_from_slice(&self.cells[r * self.cols + c]);
            }
        }
    }
}

/// Two best distances and the index of the best.
#[derive(Debug, Clone, Copy)]
struct Best2 {
    index: usize,
    first: u32,
    second: u32,
}

impl Best2 {
    const EMPTY: Best2 = Best2 {
        index: usize::MAX,
        first: u32::MAX,
        second: u32::MAX,
    };

    fn offer(&mut self, index: usize, d: u32) {
        if d < self.first {
            self.second = self.first;
            self.first = d;
            self.index = index;
        } else if d < self.second {
            self.second = d;
        }
    }

    /// The best, if it passes the ratio test (a lone candidate passes).
    fn accept(&self, nndr: f32) -> Option<(usize, u32)> {
        if self.index == usize::MAX {
            return None;
        }
        let passes = self.second == u32::MAX || (self.first as f32) < nndr * self.second as f32;
        passes.then_some((self.index, self.first))
    }
}

/// Where each query is expected in the train image: query `i` is compared only with train
/// features within `radius_px` of `projections[i]` (queries without one are skipped).
#[derive(Debug, Clone, Copy)]
pub struct Window<'a> {
    pub projections: &'a [Option<[f32; 2]>],
    pub grid: &'a PixelGrid,
    /// The train features' pixels.
    pub pixels: &'a [[f32; 2]],
    pub radius_px: f32,
}

/// Every query's nearest train descriptor that passes the ratio test, keeping for each train
/// feature only its closest query, optionally within a [`Window`].
pub fn match_descriptors(
    query: &[Descriptor],
    train: &[Descriptor],
    window: Option<Window<'_>>,
    nndr: f32,
) -> Vec<Match> {
    let mut best_for_train: Vec<Option<Match>> = vec![None; train.len()];
    let mut nearby = Vec::new();
    for (qi, q) in query.iter().enumerate() {
        let mut best = Best2::EMPTY;
        match window {
            None => {
                for (ti, t) in train.iter().enumerate() {
                    best.offer(ti, hamming(q, t));
                }
            }
            Some(Window {
                projections,
                grid,
                pixels,
                radius_px: radius,
            }) => {
                let Some(center) = projections[qi] else {
                    continue;
                };
                grid.around(center, radius, &mut nearby);
                for &ti in &nearby {
                    let p = pixels[ti];
                    let (dx, dy) = (p[0] - center[0], p[1] - center[1]);
                    if dx * dx + dy * dy <= radius * radius {
                        best.offer(ti, hamming(q, &train[ti]));
                    }
                }
            }
        }
        if let Some((ti, distance)) = best.accept(nndr) {
            let candidate = Match {
                query: qi,
                train: ti,
                distance,
            };
            let slot = &mut best_for_train[ti];
            if slot.is_none_or(|m| distance < m.distance) {
                *slot = Some(candidate);
            }
        }
    }
    let mut matches: Vec<Match> = best_for_train.into_iter().flatten().collect();
    matches.sort_unstable_by_key(|m| m.query);
    matches
}

#[cfg(test)]
mod tests {
    use super::*;

    fn descriptor(seed: u8) -> Descriptor {
        let mut d = [0u8; 32];
        for (i, b) in d.iter_mut().enumerate() {
            *b = seed
                .wrapping_mul(31)
                .wrapping_add((i as u8).wrapping_mul(seed | 1))
                .rotate_left(u32::from(seed % 7));
        }
        d
    }

    #[test]
    fn ratio_test_and_one_to_one() {
        let train: Vec<Descriptor> = (1..20).map(descriptor).collect();
        // A copy of train[3] with two bits flipped, and an exact copy of train[3] too.
        let mut near = train[3];
        near[0] ^= 0b11;
        let query = vec![near, train[3], train[7]];
        let matches = match_descriptors(&query, &train, None, 0.8);
        assert_eq!(
            matches,
            vec![
                Match {
                    query: 1,
                    train: 3,
                    distance: 0
                },
                Match {
                    query: 2,
                    train: 7,
                    distance: 0
                },
            ]
        );
        // Two identical train descriptors: the ratio test refuses to choose.
        let twins = vec![train[5], train[5]];
        assert!(match_descriptors(&[train[5]], &twins, None, 0.8).is_empty());
    }

    #[test]
    fn window_restricts_candidates() {
        let train: Vec<Descriptor> = (1..5).map(descriptor).collect();
        let pixels = [[10.0, 10.0], [100.0, 100.0], [300.0, 200.0], [600.0, 400.0]];
        let grid = PixelGrid::new(&pixels, 640, 480, 40.0);
        let query = vec![train[2], train[2]];
        let projections = [Some([305.0, 195.0]), Some([50.0, 400.0])];
        let matches = match_descriptors(
            &query,
            &train,
            Some(Window {
                projections: &projections,
                grid: &grid,
                pixels: &pixels,
                radius_px: 40.0,
            }),
            0.8,
        );
        assert_eq!(
            matches,
            vec![Match {
                query: 0,
                train: 2,
                distance: 0
            }]
        );
    }
}
