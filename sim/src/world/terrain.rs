//! Ground height field: a sum of seeded plane waves (smooth, with analytic gradient) in two
//! bands, long undulations and short bumps, plus an optional constant slope.
//!
//! A sum of sinusoids with random directions and phases is a standard way to synthesise a
//! smooth random surface with a chosen spectrum (e.g. Mastin et al. 1987, "Fourier
//! synthesis of ocean scenes"); it is infinitely differentiable, so the robot's motion on it
//! and the IMU readings derived from that motion are smooth.

use nalgebra::{Point3, Vector2};
use rand::Rng;

use super::mesh::{Material, Mesh};
use crate::config::TerrainConfig;
use crate::rng::SimRng;

/// Number of plane waves per band.
const WAVES_PER_BAND: usize = 12;

#[derive(Debug, Clone, Copy)]
struct Wave {
    k: Vector2<f64>,
    phase: f64,
    amplitude: f64,
}

/// Width over which a windowed relief fades to the flat plane.
pub const RELIEF_FADE_M: f64 = 2.0;

/// The analytic ground surface z = h(x, y).
#[derive(Debug, Clone)]
pub struct Terrain {
    waves: Vec<Wave>,
    slope: Vector2<f64>,
    /// Where the relief is whole: (min, max) corners; beyond, it fades over
    /// [`RELIEF_FADE_M`] to the plane of the slope alone. `None`: everywhere.
    window: Option<([f64; 2], [f64; 2])>,
}

/// Weight of the relief along one axis and its derivative: 1 inside `[lo, hi]`, a C1
/// smoothstep down to 0 within [`RELIEF_FADE_M`] outside.
fn fade(v: f64, lo: f64, hi: f64) -> (f64, f64) {
    let (outside, sign) = if v < lo {
        (lo - v, 1.0)
    } else if v > hi {
        (v - hi, -1.0)
    } else {
        return (1.0, 0.0);
    };
    if outside >= RELIEF_FADE_M {
        return (0.0, 0.0);
    }
    let t = 1.0 - outside / RELIEF_FADE_M;
    // d/dv of 3t² - 2t³, with dt/dv = sign / fade.
    (
        t * t * (3.0 - 2.0 * t),
        6.0 * t * (1.0 - t) * sign / RELIEF_FADE_M,
    )
}

impl Terrain {
    /// Draws the waves. `amplitude_m` is the band's peak (≈ 2σ) height.
    pub fn new(cfg: &TerrainConfig, rng: &mut SimRng) -> Self {
        let mut waves = Vec::with_capacity(2 * WAVES_PER_BAND);
        for (amplitude, wavelength) in [
            (cfg.amplitude_m, cfg.wavelength_m),
            (cfg.bump_amplitude_m, cfg.bump_wavelength_m),
        ] {
            // σ of a sum of n unit sines with random phases is sqrt(n / 2).
            let per_wave = 0.5 * amplitude / (WAVES_PER_BAND as f64 / 2.0).sqrt();
            for _ in 0..WAVES_PER_BAND {
                let direction = rng.random_range(0.0..std::f64::consts::TAU);
                // Wavelengths spread over an octave around the nominal one.
                let lambda = wavelength * 2f64.powf(rng.random_range(-0.5..0.5));
                let phase = rng.random_range(0.0..std::f64::consts::TAU);
                let k = Vector2::new(direction.cos(), direction.sin())
                    * (std::f64::consts::TAU / lambda);
                if per_wave > 0.0 {
                    waves.push(Wave {
                        k,
                        phase,
                        amplitude: per_wave,
                    });
                }
            }
        }
        let slope = Vector2::new(
            cfg.slope_deg[0].to_radians().tan(),
            cfg.slope_deg[1].to_radians().tan(),
        );
        Self {
            waves,
            slope,
            window: None,
        }
    }

    /// A flat plane at z = 0.
    pub fn flat() -> Self {
        Self {
            waves: Vec::new(),
            slope: Vector2::zeros(),
            window: None,
        }
    }

    /// The same surface with its relief kept whole over the box `min`..`max` only, fading
    /// to the flat plane (the slope alone) within [`RELIEF_FADE_M`] beyond it.
    pub fn windowed(mut self, min: [f64; 2], max: [f64; 2]) -> Self {
        self.window = Some((min, max));
        self
    }

    /// The relief's weight at (x, y) and its gradient.
    fn weight(&self, x: f64, y: f64) -> (f64, Vector2<f64>) {
        match self.window {
            None => (1.0, Vector2::zeros()),
            Some((lo, hi)) => {
                let (wx, dx) = fade(x, lo[0], hi[0]);
                let (wy, dy) = fade(y, lo[1], hi[1]);
                (wx * wy, Vector2::new(dx * wy, wx * dy))
            }
        }
    }

    /// The waves' sum at `p`, unweighted.
    fn relief(&self, p: &Vector2<f64>) -> f64 {
        self.waves
            .iter()
            .map(|w| w.amplitude * (w.k.dot(p) + w.phase).sin())
            .sum::<f64>()
    }

    pub fn height(&self, x: f64, y: f64) -> f64 {
        let p = Vector2::new(x, y);
        let (w, _) = self.weight(x, y);
        let relief = if w == 0.0 { 0.0 } else { self.relief(&p) };
        self.slope.dot(&p) + w * relief
    }

    /// (∂h/∂x, ∂h/∂y).
    pub fn gradient(&self, x: f64, y: f64) -> Vector2<f64> {
        let p = Vector2::new(x, y);
        let (w, dw) = self.weight(x, y);
        if w == 0.0 {
            return self.slope;
        }
        let relief_gradient = self.waves.iter().fold(Vector2::zeros(), |g, w| {
            g + w.k * (w.amplitude * (w.k.dot(&p) + w.phase).cos())
        });
        let relief = if dw == Vector2::zeros() {
            0.0
        } else {
            self.relief(&p)
        };
        self.slope + relief_gradient * w + dw * relief
    }

    /// Triangulates the surface over `outer` with square cells of `cell * ratio` metres,
    /// refined to `cell` over `inner` (grown to the coarse lattice) where the robot drives
    /// and the sensors look closely. The fine border vertices lie on the coarse edges, so the
    /// surface has no cracks. `material(x, y)` chooses each triangle's material from its
    /// centroid.
    pub fn mesh(
        &self,
        inner: ([f64; 2], [f64; 2]),
        outer: ([f64; 2], [f64; 2]),
        cell: f64,
        ratio: usize,
        material: impl Fn(f64, f64) -> Material,
    ) -> Mesh {
        let ratio = ratio.max(1);
        let coarse = cell * ratio as f64;
        let o = outer.0;
        let n = [0, 1].map(|k| ((outer.1[k] - o[k]) / coarse).ceil().max(1.0) as usize);
        // Inner region in coarse cells, clamped to the outer one.
        let lo =
            [0, 1].map(|k| (((inner.0[k] - o[k]) / coarse).floor().max(0.0) as usize).min(n[k]));
        let hi = [0, 1]
            .map(|k| (((inner.1[k] - o[k]) / coarse).ceil().max(0.0) as usize).clamp(lo[k], n[k]));
        // Lattice point (i, j) in fine units from the outer corner: one formula for both grids,
        // so shared border vertices are bit-identical.
        let at = |i: usize, j: usize| (o[0] + i as f64 * cell, o[1] + j as f64 * cell);
        let mut mesh = Mesh::new();

        // Coarse lattice over everything; cells inside the inner region are left to the fine one.
        let mut coarse_nodes = Vec::with_capacity((n[0] + 1) * (n[1] + 1));
        for j in 0..=n[1] {
            for i in 0..=n[0] {
                let (x, y) = at(i * ratio, j * ratio);
                coarse_nodes.push(mesh.push_vertex(Point3::new(
                    x as f32,
                    y as f32,
                    self.height(x, y) as f32,
                )));
            }
        }
        let inside =
            |i: usize, j: usize| (lo[0]..hi[0]).contains(&i) && (lo[1]..hi[1]).contains(&j);
        let centre = |i: usize, j: usize, step: usize, first: (usize, usize)| {
            let (x0, y0) = at(first.0 + i * step, first.1 + j * step);
            (x0 + 0.5 * step as f64 * cell, y0 + 0.5 * step as f64 * cell)
        };
        grid_cells(&mut mesh, &coarse_nodes, n[0], n[1], |i, j| {
            (!inside(i, j)).then(|| {
                let (x, y) = centre(i, j, ratio, (0, 0));
                material(x, y)
            })
        });

        // Fine lattice over the inner region; its border vertices lie on the coarse edges.
        let (cols, rows) = ((hi[0] - lo[0]) * ratio, (hi[1] - lo[1]) * ratio);
        let first = (lo[0] * ratio, lo[1] * ratio);
        let mut fine_nodes = Vec::with_capacity((cols + 1) * (rows + 1));
        for b in 0..=rows {
            for a in 0..=cols {
                let (x, y) = at(first.0 + a, first.1 + b);
                let along_x = (b == 0 || b == rows) && a % ratio != 0;
                let along_y = (a == 0 || a == cols) && b % ratio != 0;
                let z = if along_x || along_y {
                    let (k, f) = if along_x {
                        (a % ratio, 0)
                    } else {
                        (b % ratio, 1)
                    };
                    let w = k as f64 / ratio as f64;
                    let back = |d: usize| {
                        if f == 0 {
                            at(first.0 + a - k + d, first.1 + b)
                        } else {
                            at(first.0 + a, first.1 + b - k + d)
                        }
                    };
                    let (p0, p1) = (back(0), back(ratio));
                    let (h0, h1) = (self.height(p0.0, p0.1), self.height(p1.0, p1.1));
                    h0 + w * (h1 - h0)
                } else {
                    self.height(x, y)
                };
                fine_nodes.push(mesh.push_vertex(Point3::new(x as f32, y as f32, z as f32)));
            }
        }
        grid_cells(&mut mesh, &fine_nodes, cols, rows, |i, j| {
            let (x, y) = centre(i, j, 1, first);
            Some(material(x, y))
        });
        mesh
    }
}

/// Two triangles for every cell of a `cols × rows` lattice of vertex indices (row-major,
/// `cols + 1` per row) to which `material` gives a material; `None` skips the cell.
fn grid_cells(
    mesh: &mut Mesh,
    nodes: &[u32],
    cols: usize,
    rows: usize,
    material: impl Fn(usize, usize) -> Option<Material>,
) {
    let index = |i: usize, j: usize| nodes[j * (cols + 1) + i];
    for j in 0..rows {
        for i in 0..cols {
            if let Some(m) = material(i, j) {
                let (a, b, c, d) = (
                    index(i, j),
                    index(i + 1, j),
                    index(i + 1, j + 1),
                    index(i, j + 1),
                );
                mesh.push_triangle([a, b, c], m);
                mesh.push_triangle([a, c, d], m);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rng::stream;

    #[test]
    fn gradient_matches_finite_differences() {
        let t = Terrain::new(&TerrainConfig::default(), &mut stream(3, "terrain"));
        let h = 1e-5;
        for (x, y) in [(0.3, 1.7), (10.0, -4.0), (25.5, 12.25)] {
            let g = t.gradient(x, y);
            let gx = (t.height(x + h, y) - t.height(x - h, y)) / (2.0 * h);
            let gy = (t.height(x, y + h) - t.height(x, y - h)) / (2.0 * h);
            assert!(
                (g.x - gx).abs() < 1e-7 && (g.y - gy).abs() < 1e-7,
                "gradient {g:?} vs ({gx}, {gy})"
            );
        }
    }

    /// The graded mesh must be watertight: rays straight down anywhere, including exactly on
    /// the border between fine and coarse cells, hit the ground close to its true height.
    #[test]
    fn graded_mesh_has_no_cracks_and_follows_the_surface() {
        use crate::raycast::{Bvh, RayCaster};
        use nalgebra::Vector3;
        let t = Terrain::new(&TerrainConfig::default(), &mut stream(3, "terrain"));
        let mesh = t.mesh(
            ([0.0, 0.0], [8.0, 6.0]),
            ([-10.0, -10.0], [18.0, 16.0]),
            0.5,
            4,
            |_, _| Material::Soil,
        );
        let bvh = Bvh::build(&mesh);
        let down = Vector3::new(0.0f32, 0.0, -1.0);
        let mut worst = 0.0f64;
        for k in 0..4000 {
            // Lines across the fine/coarse borders at x = 0 and y = 6 (both on the coarse lattice).
            let (x, y) = if k % 2 == 0 {
                (0.0 + 1e-4 * f64::from(k % 3), -9.0 + 0.0061 * f64::from(k))
            } else {
                (-9.0 + 0.0067 * f64::from(k), 6.0)
            };
            let hit = bvh.cast(&Point3::new(x as f32, y as f32, 5.0), &down, 0.0, 10.0);
            let hit =
                hit.unwrap_or_else(|| panic!("ray down at ({x}, {y}) found no ground: a crack"));
            worst = worst.max((5.0 - f64::from(hit.t) - t.height(x, y)).abs());
        }
        assert!(
            worst < 0.05,
            "ground mesh departs {worst} m from the surface"
        );
    }

    #[test]
    fn windowed_relief_fades_to_the_flat_plane_with_a_matching_gradient() {
        let t = Terrain::new(&TerrainConfig::default(), &mut stream(3, "terrain"))
            .windowed([0.0, 0.0], [10.0, 5.0]);
        let h = 1e-5;
        // Inside, in the fade band on each side and at a corner, and beyond it.
        for (x, y) in [
            (5.0, 2.0),
            (-0.7, 2.0),
            (11.3, 4.0),
            (3.0, -1.9),
            (-1.0, 6.0),
        ] {
            let g = t.gradient(x, y);
            let gx = (t.height(x + h, y) - t.height(x - h, y)) / (2.0 * h);
            let gy = (t.height(x, y + h) - t.height(x, y - h)) / (2.0 * h);
            assert!(
                (g.x - gx).abs() < 1e-7 && (g.y - gy).abs() < 1e-7,
                "at ({x}, {y}): gradient {g:?} vs ({gx}, {gy})"
            );
        }
        let unwindowed = Terrain::new(&TerrainConfig::default(), &mut stream(3, "terrain"));
        assert_eq!(t.height(5.0, 2.0), unwindowed.height(5.0, 2.0));
        assert!(unwindowed.height(5.0, 2.0).abs() > 1e-4, "a relief to fade");
        for (x, y) in [(-2.0, 2.0), (12.5, 0.0), (5.0, 40.0)] {
            assert_eq!(t.height(x, y), 0.0, "flat at ({x}, {y})");
        }
    }

    #[test]
    fn heights_stay_near_the_configured_amplitude() {
        let cfg = TerrainConfig::default();
        let t = Terrain::new(&cfg, &mut stream(3, "terrain"));
        let peak = (0..2000)
            .map(|i| t.height(f64::from(i) * 0.05, f64::from(i % 37) * 0.7).abs())
            .fold(0.0, f64::max);
        let bound = 2.0 * (cfg.amplitude_m + cfg.bump_amplitude_m);
        assert!(
            peak > 0.02 && peak < bound,
            "peak height {peak} should be non-zero and below {bound}"
        );
    }
}
