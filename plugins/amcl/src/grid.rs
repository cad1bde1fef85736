//! The map AMCL localises in: an occupancy grid in the ROS `map_server` convention, and the
//! likelihood field made from it (each cell's distance to the nearest occupied cell).

use std::cmp::Reverse;
use std::collections::BinaryHeap;

use rand::Rng;

use crate::Pose2;

/// An occupancy grid: cells row-major from the cell at `origin` (x right, y up, no yaw),
/// values 0 (free) to 100 (occupied), -1 unknown. As AMCL reads a map (`convertMap`), 0 is
/// free, 100 occupied and anything else unknown (`map_server` has already thresholded an
/// image into these three).
#[derive(Debug, Clone, PartialEq)]
pub struct Grid {
    pub resolution_m: f64,
    /// World position of cell (0, 0)'s corner, metres.
    pub origin: [f64; 2],
    pub width: usize,
    pub height: usize,
    pub cells: Vec<i8>,
}

/// What a cell is to the filter.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Occupancy {
    Free,
    Occupied,
    Unknown,
}

impl Grid {
    /// A grid; errors with one line if the cells do not fill `width` x `height` or the
    /// resolution is not positive.
    pub fn new(
        resolution_m: f64,
        origin: [f64; 2],
        width: usize,
        height: usize,
        cells: Vec<i8>,
    ) -> Result<Self, String> {
        if !(resolution_m.is_finite() && resolution_m > 0.0) {
            return Err(format!(
                "grid resolution must be positive, got {resolution_m}"
            ));
        }
        if cells.len() != width * height || width == 0 || height == 0 {
            return Err(format!(
                "grid of {width} x {height} cells holds {} values",
                cells.len()
            ));
        }
        if !origin.iter().all(|v| v.is_finite()) {
            return Err(format!("grid origin is not finite: {origin:?}"));
        }
        Ok(Self {
            resolution_m,
            origin,
            width,
            height,
            cells,
        })
    }

    pub fn occupancy(&self, i: usize, j: usize) -> Occupancy {
        match self.cells[j * self.width + i] {
            100 => Occupancy::Occupied,
            0 => Occupancy::Free,
            _ => Occupancy::Unknown,
        }
    }

    /// The cell holding a world position, if inside the grid.
    pub fn cell_of(&self, x: f64, y: f64) -> Option<(usize, usize)> {
        let i = ((x - self.origin[0]) / self.resolution_m).floor();
        let j = ((y - self.origin[1]) / self.resolution_m).floor();
        (i >= 0.0 && j >= 0.0 && (i as usize) < self.width && (j as usize) < self.height)
            .then_some((i as usize, j as usize))
    }

    /// A cell's centre in the world.
    pub fn centre(&self, i: usize, j: usize) -> [f64; 2] {
        [
            self.origin[0] + (i as f64 + 0.5) * self.resolution_m,
            self.origin[1] + (j as f64 + 0.5) * self.resolution_m,
        ]
    }
}

/// The likelihood field: for each cell, the distance to the nearest occupied cell, capped
/// at `max_dist` (AMCL's `laser_likelihood_max_dist`; beyond the grid, the cap), and the
/// free cells, where global localisation and recovery draw their random particles.
#[derive(Debug, Clone)]
pub struct LikelihoodField {
    pub grid: Grid,
    pub max_dist: f64,
    distance: Vec<f32>,
    free: Vec<(u32, u32)>,
}

impl LikelihoodField {
    /// Computes the distances by a wavefront from every occupied cell (a Dijkstra
    /// expansion in which each cell keeps its nearest source and the distance is the
    /// Euclidean one to it, as AMCL's `map_update_cspace` does), stopping at `max_dist`.
    pub fn new(grid: Grid, max_dist: f64) -> Self {
        let (w, h) = (grid.width, grid.height);
        let mut distance = vec![max_dist as f32; w * h];
        let mut source = vec![u32::MAX; w * h];
        let mut heap = BinaryHeap::new();
        let mut free = Vec::new();
        for j in 0..h {
            for i in 0..w {
                match grid.occupancy(i, j) {
                    Occupancy::Occupied => {
                        let k = j * w + i;
                        distance[k] = 0.0;
                        source[k] = k as u32;
                        heap.push(Reverse((0u64, k as u32)));
                    }
                    Occupancy::Free => free.push((i as u32, j as u32)),
                    Occupancy::Unknown => {}
                }
            }
        }
        let res = grid.resolution_m;
        while let Some(Reverse((d_bits, k))) = heap.pop() {
            let k = k as usize;
            let d = f64::from_bits(d_bits);
            if (d as f32) > distance[k] {
                continue;
            }
            let (i, j) = ((k % w) as i64, (k / w) as i64);
            let s = source[k] as usize;
            let (si, sj) = ((s % w) as i64, (s / w) as i64);
            for (di, dj) in [(-1, 0), (1, 0), (0, -1), (0, 1)] {
                let (ni, nj) = (i + di, j + dj);
                if ni < 0 || nj < 0 || ni >= w as i64 || nj >= h as i64 {
                    continue;
                }
                let nk = nj as usize * w + ni as usize;
                let nd = (((ni - si).pow(2) + (nj - sj).pow(2)) as f64).sqrt() * res;
                if nd < max_dist && (nd as f32) < distance[nk] {
                    distance[nk] = nd as f32;
                    source[nk] = s as u32;
                    heap.push(Reverse((nd.to_bits(), nk as u32)));
                }
            }
        }
        Self {
            grid,
            max_dist,
            distance,
            free,
        }
    }

    /// The distance from a world position to the nearest occupied cell (the cap off the
    /// grid).
    pub fn distance_at(&self, x: f64, y: f64) -> f64 {
        match self.grid.cell_of(x, y) {
            Some((i, j)) => f64::from(self.distance[j * self.grid.width + i]),
            None => self.max_dist,
        }
    }

    /// How many free cells there are.
    pub fn free_cells(&self) -> usize {
        self.free.len()
    }

    /// A pose at the centre of a random free cell with a uniform heading (AMCL's uniform
    /// pose generator); `None` on a grid without a free cell.
    pub fn random_free_pose(&self, rng: &mut impl Rng) -> Option<Pose2> {
        if self.free.is_empty() {
            return None;
        }
        let (i, j) = self.free[rng.random_range(0..self.free.len())];
        let [x, y] = self.grid.centre(i as usize, j as usize);
        let theta = rng.random_range(-std::f64::consts::PI..std::f64::consts::PI);
        Some(Pose2::new(x, y, theta))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A 10 m x 6 m free room at 0.1 m with walls on its border and one occupied cell.
    pub(crate) fn room() -> Grid {
        let (w, h) = (100, 60);
        let mut cells = vec![0i8; w * h];
        for j in 0..h {
            for i in 0..w {
                if i == 0 || j == 0 || i == w - 1 || j == h - 1 {
                    cells[j * w + i] = 100;
                }
            }
        }
        cells[30 * w + 50] = 100;
        Grid::new(0.1, [0.0, 0.0], w, h, cells).expect("valid")
    }

    #[test]
    fn the_field_is_the_distance_to_the_nearest_occupied_cell_capped() {
        let f = LikelihoodField::new(room(), 2.0);
        // On the lone occupied cell's centre (5.05, 3.05): 0; 1 m east of it: 1 m.
        assert_eq!(f.distance_at(5.05, 3.05), 0.0);
        assert!((f.distance_at(6.05, 3.05) - 1.0).abs() < 1e-6);
        // Diagonal, 0.3 m and 0.4 m away: 0.5 m (Euclidean, not city-block).
        assert!(
            (f.distance_at(5.35, 3.45) - 0.5).abs() < 1e-6,
            "{}",
            f.distance_at(5.35, 3.45)
        );
        // 0.25 m inside the west wall's cell centre (0.05): 0.2 m.
        assert!((f.distance_at(0.25, 1.55) - 0.2).abs() < 1e-6);
        // Far from everything, the cap; off the grid, the cap.
        assert_eq!(f.distance_at(2.55, 2.55), 2.0);
        assert_eq!(f.distance_at(-5.0, 2.0), 2.0);
        assert_eq!(f.free_cells(), 98 * 58 - 1);
    }

    #[test]
    fn random_poses_land_on_free_cells_only() {
        use rand::SeedableRng;
        let f = LikelihoodField::new(room(), 2.0);
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(3);
        for _ in 0..1000 {
            let p = f.random_free_pose(&mut rng).expect("free cells");
            let (i, j) = f.grid.cell_of(p.x, p.y).expect("inside");
            assert_eq!(f.grid.occupancy(i, j), Occupancy::Free);
        }
    }

    #[test]
    fn a_grid_that_does_not_fit_its_cells_is_one_line() {
        let e = Grid::new(0.1, [0.0, 0.0], 4, 4, vec![0; 15]).expect_err("short");
        assert_eq!(e, "grid of 4 x 4 cells holds 15 values");
        assert!(Grid::new(0.0, [0.0, 0.0], 1, 1, vec![0]).is_err());
    }
}
