//! The world's surveyed occupancy grid: what a lab's map of the block at the 2D lidars' scan
//! height shows, built from the world's geometry rather than by a robot (issue 46's `amcl`
//! row localising in the surveyed grid, beside the row localising in a grid a SLAM run
//! built).
//!
//! A cell is occupied where any surface of the world crosses the plane `height_m` above the
//! local ground (the terrain is uneven, so the plane follows it, as a scanner on a robot
//! following the ground does), free elsewhere over the modelled ground. A survey of the
//! permanent structure (posts, trunks, cordons, fence) is the world at growth stage 0;
//! at a later stage the canopy that crosses the plane is in it as well.

use nalgebra::Point3;

use super::World;

/// An occupancy grid in the ROS `map_server` convention: row-major from the cell at
/// `origin` (x right, y up), 0 free, 100 occupied.
#[derive(Debug, Clone, PartialEq)]
pub struct SurveyedGrid {
    pub resolution_m: f64,
    /// World position of cell (0, 0)'s corner.
    pub origin: [f64; 2],
    pub width: usize,
    pub height: usize,
    pub cells: Vec<i8>,
}

impl SurveyedGrid {
    /// The cell of a world position, if inside.
    pub fn cell_of(&self, x: f64, y: f64) -> Option<(usize, usize)> {
        let i = ((x - self.origin[0]) / self.resolution_m).floor();
        let j = ((y - self.origin[1]) / self.resolution_m).floor();
        (i >= 0.0 && j >= 0.0 && (i as usize) < self.width && (j as usize) < self.height)
            .then_some((i as usize, j as usize))
    }

    /// The value of the cell holding a world position (`None` outside the grid).
    pub fn at(&self, x: f64, y: f64) -> Option<i8> {
        self.cell_of(x, y)
            .map(|(i, j)| self.cells[j * self.width + i])
    }
}

impl World {
    /// The occupancy grid of this world at `height_m` above the ground, `resolution_m` cells
    /// over the modelled ground's extent (see the module documentation).
    pub fn surveyed_grid(&self, height_m: f64, resolution_m: f64) -> SurveyedGrid {
        assert!(resolution_m > 0.0 && height_m.is_finite(), "a valid survey");
        let ([x0, y0], [x1, y1]) = self.extent;
        let width = ((x1 - x0) / resolution_m).ceil().max(1.0) as usize;
        let height = ((y1 - y0) / resolution_m).ceil().max(1.0) as usize;
        let mut grid = SurveyedGrid {
            resolution_m,
            origin: [x0, y0],
            width,
            height,
            cells: vec![0; width * height],
        };
        let above = |p: &Point3<f32>| {
            let (x, y) = (f64::from(p.x), f64::from(p.y));
            f64::from(p.z) - (self.terrain.height(x, y) + height_m)
        };
        let mesh = &self.mesh;
        let side: Vec<f64> = mesh.vertices.iter().map(above).collect();
        for tri in &mesh.triangles {
            let v = tri.map(|k| k as usize);
            let d = v.map(|k| side[k]);
            if d.iter().all(|&s| s > 0.0) || d.iter().all(|&s| s < 0.0) {
                continue;
            }
            // Where the plane crosses the triangle's edges (a vertex on the plane counts
            // as a crossing of its edges).
            let mut ends: Vec<[f64; 2]> = Vec::with_capacity(3);
            for (a, b) in [(0, 1), (1, 2), (2, 0)] {
                let (da, db) = (d[a], d[b]);
                if (da <= 0.0 && db >= 0.0) || (da >= 0.0 && db <= 0.0) {
                    let t = if da == db { 0.0 } else { da / (da - db) };
                    let (pa, pb) = (&mesh.vertices[v[a]], &mesh.vertices[v[b]]);
                    ends.push([
                        f64::from(pa.x) + t * f64::from(pb.x - pa.x),
                        f64::from(pa.y) + t * f64::from(pb.y - pa.y),
                    ]);
                }
            }
            // The segment between the crossings, marked every half cell.
            let (p, q) = match ends.as_slice() {
                [p] => (*p, *p),
                [p, q, ..] => (*p, *q),
                [] => continue,
            };
            let length = (q[0] - p[0]).hypot(q[1] - p[1]);
            let steps = (2.0 * length / resolution_m).ceil() as usize;
            for s in 0..=steps {
                let t = if steps == 0 {
                    0.0
                } else {
                    s as f64 / steps as f64
                };
                let (x, y) = (p[0] + t * (q[0] - p[0]), p[1] + t * (q[1] - p[1]));
                if let Some((i, j)) = grid.cell_of(x, y) {
                    grid.cells[j * width + i] = 100;
                }
            }
        }
        grid
    }
}

#[cfg(test)]
mod tests {
    use crate::config::{SimConfig, VineyardConfig};
    use crate::world::World;

    /// Our world at growth stage 0, surveyed at 0.4 m: every post and every plant's trunk
    /// is in it, a lane's middle and the headlands are free, and so is the space over the
    /// ground at a height where nothing stands.
    #[test]
    fn a_survey_shows_the_posts_and_trunks_and_keeps_the_lanes_free() {
        let cfg = SimConfig {
            vineyard: VineyardConfig {
                growth_stage: 0.0,
                ..VineyardConfig::default()
            },
            ..SimConfig::default()
        };
        let w = World::from_config(&cfg);
        let g = w.surveyed_grid(0.4, 0.05);
        // Within three cells (0.15 m) of a place, in cell indices.
        let occupied_near = |x: f64, y: f64| {
            let (i, j) = g.cell_of(x, y).expect("inside");
            (i - 3..=i + 3).any(|i| (j - 3..=j + 3).any(|j| g.cells[j * g.width + i] == 100))
        };
        for p in &w.posts {
            assert!(
                occupied_near(p.x, p.y),
                "post at ({:.2}, {:.2}) missing",
                p.x,
                p.y
            );
        }
        for p in &w.plants {
            assert!(
                occupied_near(p.base.x, p.base.y),
                "trunk at ({:.2}, {:.2}) missing",
                p.base.x,
                p.base.y
            );
        }
        // The middle of the first lane (rows run along x, one every row spacing in y),
        // along its length, is free.
        let v = &w.vineyard;
        let lane_y = 0.5 * v.row_spacing_m;
        let (lo, hi) = super::super::block_bounds(v);
        let mut x = lo[0] + 1.0;
        while x < hi[0] - 1.0 {
            assert_eq!(g.at(x, lane_y), Some(0), "lane middle at x = {x:.2}");
            x += 0.25;
        }
        let occupied = g.cells.iter().filter(|&&c| c == 100).count();
        assert!(occupied > w.plants.len(), "{occupied} occupied cells");
        // 10 m up, nothing stands.
        assert!(w.surveyed_grid(10.0, 0.05).cells.iter().all(|&c| c == 0));
    }
}
