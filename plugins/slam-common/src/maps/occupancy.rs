//! A 2D occupancy grid from planar laser scans, by log-odds occupancy mapping (Moravec and
//! Elfes, "High resolution maps from wide angle sonar", ICRA 1985; Thrun, Burgard and Fox,
//! *Probabilistic Robotics*, ch. 9, the inverse sensor model with a uniform prior).
//!
//! Every cell holds `l = log(p / (1 − p))`, unknown until a ray first reaches it (then as if
//! from the prior `p = 0.5`, `l = 0`). A scan's rays are traversed cell by cell with
//! Amanatides and Woo's algorithm ("A fast voxel traversal algorithm for ray tracing",
//! Eurographics 1987), which visits exactly the cells the segment crosses: the cells before
//! a return are free, the cell of the return occupied. As in OctoMap (Hornung et al.,
//! Autonomous Robots 2013), whose parameters RTAB-Map's `Grid/` defaults are, each cell is
//! updated at most once per scan, occupied winning over free (so that neighbouring rays
//! grazing a trunk do not erase it), with `l += logit(prob_hit)` or `l += logit(prob_miss)`,
//! and `l` is clamped to `[logit(clamping_min), logit(clamping_max)]` so that the map stays
//! able to change.
//!
//! Rays with no return (`+inf` in a ROS scan, see
//! [`crate::registration::scan2d::no_return_directions`]) clear free space up to
//! [`OccupancyGridConfig::no_return_range_m`]; that is off by default, like RTAB-Map's
//! `Grid/Scan2dUnknownSpaceFilled`, since "nothing within range" near a vine row usually
//! means a gap in the foliage rather than 30 m of open ground. Returns beyond
//! [`OccupancyGridConfig::max_range_m`] (`Grid/RangeMax`) are cut there and mark free cells
//! only.
//!
//! The grid needs no bounds: cells are anchored at multiples of the resolution in the
//! world frame and the stored array grows (with a margin) to cover each new scan. The
//! [`Grid`] that [`OccupancyGridBuilder::build`] returns is cropped to the cells observed,
//! so it does not depend on how the array grew.

use nalgebra::{Isometry2, Point2, Vector2};
use serde::Deserialize;
use thiserror::Error;

/// Settings of an [`OccupancyGridBuilder`], RTAB-Map's defaults (names in brackets).
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct OccupancyGridConfig {
    /// Cell edge, m (`Grid/CellSize`, 0.05).
    pub resolution_m: f64,
    /// Probability that a cell with a return is occupied (`Grid/ProbHit`, 0.7).
    pub prob_hit: f64,
    /// Probability that a cell a ray crossed is occupied (`Grid/ProbMiss`, 0.4).
    pub prob_miss: f64,
    /// Clamping of the cell probabilities (`Grid/ProbClampingMin` 0.1192,
    /// `Grid/ProbClampingMax` 0.971).
    pub clamping_min: f64,
    pub clamping_max: f64,
    /// An observed cell is occupied (100) above this probability, free (0) below it and
    /// unknown (-1) exactly at it (`Grid/OccupancyThr`, 0.5).
    pub occupancy_threshold: f64,
    /// Returns farther than this are cut here and mark free cells only, m; 0 for no limit
    /// (`Grid/RangeMax`; default 0: the scan's own `range_max` applies).
    pub max_range_m: f64,
    /// Rays with no return mark free cells up to this range, m (capped by `max_range_m`);
    /// 0 leaves them out (the default).
    pub no_return_range_m: f64,
}

impl Default for OccupancyGridConfig {
    fn default() -> Self {
        Self {
            resolution_m: 0.05,
            prob_hit: 0.7,
            prob_miss: 0.4,
            clamping_min: 0.1192,
            clamping_max: 0.971,
            occupancy_threshold: 0.5,
            max_range_m: 0.0,
            no_return_range_m: 0.0,
        }
    }
}

/// A setting of [`OccupancyGridConfig`] out of its domain.
#[derive(Debug, Clone, PartialEq, Error)]
#[error("occupancy grid: {0}")]
pub struct InvalidOccupancyConfig(String);

/// An occupancy grid in the ROS `nav_msgs/OccupancyGrid` / map_server convention: `cells`
/// row-major from cell (0, 0) at `origin`, the lower-left corner; column index along x
/// (right), row index along y (up); 0 free, 100 occupied, -1 unknown. The same fields as
/// the plugin API's `OccupancyGrid`.
#[derive(Debug, Clone, PartialEq)]
pub struct Grid {
    pub resolution_m: f64,
    /// World position of cell (0, 0)'s lower-left corner and the grid's yaw (always 0
    /// here): `[x, y, yaw]`.
    pub origin: [f64; 3],
    pub width: u32,
    pub height: u32,
    pub cells: Vec<i8>,
}

impl Grid {
    pub const FREE: i8 = 0;
    pub const OCCUPIED: i8 = 100;
    pub const UNKNOWN: i8 = -1;

    /// `(column, row)` of the cell holding the world point, if inside the grid (yaw 0).
    pub fn cell_of(&self, world: &Vector2<f64>) -> Option<(u32, u32)> {
        let col = ((world.x - self.origin[0]) / self.resolution_m).floor();
        let row = ((world.y - self.origin[1]) / self.resolution_m).floor();
        (col >= 0.0 && row >= 0.0 && col < f64::from(self.width) && row < f64::from(self.height))
            .then_some((col as u32, row as u32))
    }

    /// The value of cell `(column, row)`.
    pub fn at(&self, col: u32, row: u32) -> i8 {
        self.cells[row as usize * self.width as usize + col as usize]
    }

    /// The value of the cell holding the world point; unknown outside the grid.
    pub fn value_at(&self, world: &Vector2<f64>) -> i8 {
        self.cell_of(world)
            .map_or(Self::UNKNOWN, |(c, r)| self.at(c, r))
    }
}

fn logit(p: f64) -> f32 {
    (p / (1.0 - p)).ln() as f32
}

/// Cells of margin added on each side the array grows towards (at least).
const GROWTH_MARGIN: i64 = 64;

/// Accumulates laser scans into log-odds cells; see the module docs.
#[derive(Debug, Clone)]
pub struct OccupancyGridBuilder {
    config: OccupancyGridConfig,
    l_hit: f32,
    l_miss: f32,
    l_min: f32,
    l_max: f32,
    l_threshold: f32,
    /// World cell index of the array's cell (0, 0).
    min_cell: [i64; 2],
    width: usize,
    height: usize,
    /// Log-odds per cell, row-major; NaN for never observed.
    log_odds: Vec<f32>,
    /// Per-scan scratch: indices of the cells crossed and hit.
    free: Vec<usize>,
    hit: Vec<usize>,
}

impl OccupancyGridBuilder {
    pub fn new(config: OccupancyGridConfig) -> Result<Self, InvalidOccupancyConfig> {
        let c = &config;
        let bad = |what: &str| Err(InvalidOccupancyConfig(what.to_owned()));
        if !(c.resolution_m > 0.0 && c.resolution_m.is_finite()) {
            return bad("resolution_m must be positive");
        }
        let open = |p: f64| p > 0.0 && p < 1.0;
        let probabilities = [
            c.prob_hit,
            c.prob_miss,
            c.clamping_min,
            c.clamping_max,
            c.occupancy_threshold,
        ];
        if !probabilities.into_iter().all(open) {
            return bad("probabilities must lie strictly between 0 and 1");
        }
        if !(c.prob_hit > 0.5 && c.prob_miss < 0.5) {
            return bad("prob_hit must exceed 0.5 and prob_miss be below it");
        }
        if !(c.clamping_min < c.occupancy_threshold && c.occupancy_threshold < c.clamping_max) {
            return bad("need clamping_min < occupancy_threshold < clamping_max");
        }
        if !(c.max_range_m >= 0.0 && c.no_return_range_m >= 0.0) {
            return bad("ranges must be non-negative (0: off)");
        }
        Ok(Self {
            l_hit: logit(c.prob_hit),
            l_miss: logit(c.prob_miss),
            l_min: logit(c.clamping_min),
            l_max: logit(c.clamping_max),
            l_threshold: logit(c.occupancy_threshold),
            config,
            min_cell: [0, 0],
            width: 0,
            height: 0,
            log_odds: Vec::new(),
            free: Vec::new(),
            hit: Vec::new(),
        })
    }

    pub fn config(&self) -> &OccupancyGridConfig {
        &self.config
    }

    /// Adds one scan taken at `world_from_sensor`: `points_in_sensor` are its returns,
    /// `no_return_directions` the directions (sensor frame, any length) of its rays that
    /// met nothing. Non-finite points and directions are skipped.
    pub fn insert_scan(
        &mut self,
        world_from_sensor: &Isometry2<f64>,
        points_in_sensor: &[Vector2<f64>],
        no_return_directions: &[Vector2<f64>],
    ) {
        let origin = world_from_sensor.translation.vector;
        let cap = |r: f64| {
            if self.config.max_range_m > 0.0 {
                r.min(self.config.max_range_m)
            } else {
                r
            }
        };
        let finite = |v: &&Vector2<f64>| v.x.is_finite() && v.y.is_finite();
        // Ray ends in the world, and whether they are returns.
        let mut rays: Vec<(Vector2<f64>, bool)> = points_in_sensor
            .iter()
            .filter(finite)
            .map(|p| {
                let r = p.norm();
                let kept = cap(r);
                let end = if kept < r { p * (kept / r) } else { *p };
                ((world_from_sensor * Point2::from(end)).coords, kept >= r)
            })
            .collect();
        if self.config.no_return_range_m > 0.0 {
            let length = cap(self.config.no_return_range_m);
            rays.extend(
                no_return_directions
                    .iter()
                    .filter(finite)
                    .filter(|d| d.norm() > 0.0)
                    .map(|d| {
                        let end = world_from_sensor * Point2::from(d.normalize() * length);
                        (end.coords, false)
                    }),
            );
        }
        if rays.is_empty() {
            return;
        }
        let inv = 1.0 / self.config.resolution_m;
        let cell = |v: &Vector2<f64>| [(v.x * inv).floor() as i64, (v.y * inv).floor() as i64];
        let (mut lo, mut hi) = (cell(&origin), cell(&origin));
        for (end, _) in &rays {
            let c = cell(end);
            for a in 0..2 {
                lo[a] = lo[a].min(c[a]);
                hi[a] = hi[a].max(c[a]);
            }
        }
        self.cover(lo, hi);

        // Continuous cell coordinates relative to the array.
        let local = |v: &Vector2<f64>| {
            Vector2::new(
                v.x * inv - self.min_cell[0] as f64,
                v.y * inv - self.min_cell[1] as f64,
            )
        };
        let start = local(&origin);
        let (width, mut free, mut hit) = (
            self.width,
            std::mem::take(&mut self.free),
            std::mem::take(&mut self.hit),
        );
        free.clear();
        hit.clear();
        for (end, is_return) in &rays {
            let [ex, ey] = traverse(start, local(end), |x, y| {
                free.push(y as usize * width + x as usize);
            });
            let end_index = ey as usize * width + ex as usize;
            if *is_return {
                hit.push(end_index);
            } else {
                free.push(end_index);
            }
        }
        hit.sort_unstable();
        hit.dedup();
        free.sort_unstable();
        free.dedup();
        free.retain(|i| hit.binary_search(i).is_err());
        for &i in &free {
            self.update(i, self.l_miss);
        }
        for &i in &hit {
            self.update(i, self.l_hit);
        }
        self.free = free;
        self.hit = hit;
    }

    fn update(&mut self, index: usize, delta: f32) {
        let l = &mut self.log_odds[index];
        let prior = if l.is_nan() { 0.0 } else { *l };
        *l = (prior + delta).clamp(self.l_min, self.l_max);
    }

    /// Grows the array so that it holds world cells `lo..=hi`.
    fn cover(&mut self, lo: [i64; 2], hi: [i64; 2]) {
        let (w, h) = (self.width as i64, self.height as i64);
        let cur_lo = self.min_cell;
        let cur_hi = [cur_lo[0] + w - 1, cur_lo[1] + h - 1];
        if w > 0 && (0..2).all(|a| lo[a] >= cur_lo[a] && hi[a] <= cur_hi[a]) {
            return;
        }
        let mut new_lo = [0i64; 2];
        let mut new_hi = [0i64; 2];
        for a in 0..2 {
            let margin = GROWTH_MARGIN.max([w, h][a] / 4);
            if w == 0 {
                new_lo[a] = lo[a] - margin;
                new_hi[a] = hi[a] + margin;
            } else {
                new_lo[a] = if lo[a] < cur_lo[a] {
                    lo[a] - margin
                } else {
                    cur_lo[a]
                };
                new_hi[a] = if hi[a] > cur_hi[a] {
                    hi[a] + margin
                } else {
                    cur_hi[a]
                };
            }
        }
        let new_w = (new_hi[0] - new_lo[0] + 1) as usize;
        let new_h = (new_hi[1] - new_lo[1] + 1) as usize;
        let mut cells = vec![f32::NAN; new_w * new_h];
        if w > 0 {
            let dx = (cur_lo[0] - new_lo[0]) as usize;
            let dy = (cur_lo[1] - new_lo[1]) as usize;
            for (row, old) in self.log_odds.chunks_exact(self.width).enumerate() {
                let at = (row + dy) * new_w + dx;
                cells[at..at + self.width].copy_from_slice(old);
            }
        }
        self.min_cell = new_lo;
        self.width = new_w;
        self.height = new_h;
        self.log_odds = cells;
    }

    /// The occupancy probability of the cell holding the world point; None if unknown.
    pub fn probability(&self, world: &Vector2<f64>) -> Option<f64> {
        let inv = 1.0 / self.config.resolution_m;
        let x = (world.x * inv).floor() as i64 - self.min_cell[0];
        let y = (world.y * inv).floor() as i64 - self.min_cell[1];
        if x < 0 || y < 0 || x >= self.width as i64 || y >= self.height as i64 {
            return None;
        }
        let l = self.log_odds[y as usize * self.width + x as usize];
        (!l.is_nan()).then(|| 1.0 - 1.0 / (1.0 + f64::from(l).exp()))
    }

    /// The grid of the cells observed so far (their bounding box; unknown cells inside it
    /// are -1). Empty (0 × 0, origin 0) before any ray.
    pub fn build(&self) -> Grid {
        let observed = |x: usize, y: usize| !self.log_odds[y * self.width + x].is_nan();
        let rows: Vec<usize> = (0..self.height)
            .filter(|&y| (0..self.width).any(|x| observed(x, y)))
            .collect();
        let cols: Vec<usize> = (0..self.width)
            .filter(|&x| rows.iter().any(|&y| observed(x, y)))
            .collect();
        let res = self.config.resolution_m;
        let (Some(&y0), Some(&y1), Some(&x0), Some(&x1)) =
            (rows.first(), rows.last(), cols.first(), cols.last())
        else {
            return Grid {
                resolution_m: res,
                origin: [0.0, 0.0, 0.0],
                width: 0,
                height: 0,
                cells: Vec::new(),
            };
        };
        let mut cells = Vec::with_capacity((x1 - x0 + 1) * (y1 - y0 + 1));
        for y in y0..=y1 {
            let row = &self.log_odds[y * self.width..(y + 1) * self.width];
            cells.extend(row[x0..=x1].iter().map(|&l| {
                if l.is_nan() || l == self.l_threshold {
                    Grid::UNKNOWN
                } else if l > self.l_threshold {
                    Grid::OCCUPIED
                } else {
                    Grid::FREE
                }
            }));
        }
        Grid {
            resolution_m: res,
            origin: [
                (self.min_cell[0] + x0 as i64) as f64 * res,
                (self.min_cell[1] + y0 as i64) as f64 * res,
                0.0,
            ],
            width: (x1 - x0 + 1) as u32,
            height: (y1 - y0 + 1) as u32,
            cells,
        }
    }
}

/// Visits the cells the segment `a → b` (continuous cell coordinates, both inside the
/// array) crosses before the cell of `b`, in order, and returns the cell of `b`
/// (Amanatides and Woo). The number of steps is fixed by the two end cells, so rounding
/// can neither skip the end cell nor overshoot it.
fn traverse(a: Vector2<f64>, b: Vector2<f64>, mut visit: impl FnMut(i64, i64)) -> [i64; 2] {
    let mut c = [a.x.floor() as i64, a.y.floor() as i64];
    let end = [b.x.floor() as i64, b.y.floor() as i64];
    let d = b - a;
    let mut step = [0i64; 2];
    let mut t_max = [f64::INFINITY; 2];
    let mut t_delta = [f64::INFINITY; 2];
    for k in 0..2 {
        if d[k] > 0.0 {
            step[k] = 1;
            t_max[k] = (c[k] as f64 + 1.0 - a[k]) / d[k];
            t_delta[k] = 1.0 / d[k];
        } else if d[k] < 0.0 {
            step[k] = -1;
            t_max[k] = (a[k] - c[k] as f64) / -d[k];
            t_delta[k] = -1.0 / d[k];
        }
    }
    let steps = (end[0] - c[0]).abs() + (end[1] - c[1]).abs();
    for _ in 0..steps {
        visit(c[0], c[1]);
        let k = if c[1] == end[1] || (c[0] != end[0] && t_max[0] < t_max[1]) {
            0
        } else {
            1
        };
        c[k] += step[k];
        t_max[k] += t_delta[k];
    }
    end
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn traversal_visits_the_crossed_cells() {
        let mut seen = Vec::new();
        let end = traverse(Vector2::new(0.5, 0.5), Vector2::new(3.5, 1.7), |x, y| {
            seen.push((x, y))
        });
        assert_eq!(end, [3, 1]);
        // y = 0.5 + 0.4 (x − 0.5) crosses y = 1 at x = 1.75.
        assert_eq!(seen, vec![(0, 0), (1, 0), (1, 1), (2, 1)]);
        seen.clear();
        let end = traverse(Vector2::new(2.2, 2.7), Vector2::new(2.9, -0.4), |x, y| {
            seen.push((x, y))
        });
        assert_eq!(end, [2, -1]);
        assert_eq!(seen, vec![(2, 2), (2, 1), (2, 0)]);
    }

    #[test]
    fn rejects_inverted_probabilities() {
        let config = OccupancyGridConfig {
            prob_hit: 0.4,
            ..OccupancyGridConfig::default()
        };
        assert!(OccupancyGridBuilder::new(config).is_err());
        assert!(OccupancyGridBuilder::new(OccupancyGridConfig::default()).is_ok());
    }

    #[test]
    fn growing_keeps_the_cells() {
        let mut b = OccupancyGridBuilder::new(OccupancyGridConfig::default()).expect("valid");
        let at = Isometry2::identity();
        b.insert_scan(&at, &[Vector2::new(1.0, 0.02)], &[]);
        let before = b.build();
        // Far away in −x and +y: the array grows on both sides.
        b.insert_scan(
            &Isometry2::new(Vector2::new(-20.0, 15.0), 0.0),
            &[Vector2::new(0.5, 0.02)],
            &[],
        );
        let after = b.build();
        for p in [Vector2::new(1.02, 0.02), Vector2::new(0.5, 0.02)] {
            assert_eq!(before.value_at(&p), after.value_at(&p), "{p:?}");
        }
        assert_eq!(after.value_at(&Vector2::new(1.02, 0.02)), Grid::OCCUPIED);
        assert_eq!(after.value_at(&Vector2::new(-19.48, 15.02)), Grid::OCCUPIED);
    }
}
