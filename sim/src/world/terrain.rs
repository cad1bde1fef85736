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

/// The analytic ground surface z = h(x, y).
#[derive(Debug, Clone)]
pub struct Terrain {
    waves: Vec<Wave>,
    slope: Vector2<f64>,
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
                let k = Vector2::new(direction.cos(), direction.sin()) * (std::f64::consts::TAU / lambda);
                if per_wave > 0.0 {
                    waves.push(Wave {
                        k,
                        phase,
                        amplitude: per_wave,
                    });
                }
            }
        }
        let slope = Vector2::new(cfg.slope_deg[0].to_radians().tan(), cfg.slope_deg[1].to_radians().tan());
        Self { waves, slope }
    }

    /// A flat plane at z = 0.
    pub fn flat() -> Self {
        Self {
            waves: Vec::new(),
            slope: Vector2::zeros(),
        }
    }

    pub fn height(&self, x: f64, y: f64) -> f64 {
        let p = Vector2::new(x, y);
        self.slope.dot(&p)
            + self
                .waves
                .iter()
                .map(|w| w.amplitude * (w.k.dot(&p) + w.phase).sin())
                .sum::<f64>()
    }

    /// (∂h/∂x, ∂h/∂y).
    pub fn gradient(&self, x: f64, y: f64) -> Vector2<f64> {
        let p = Vector2::new(x, y);
        self.waves.iter().fold(self.slope, |g, w| {
            g + w.k * (w.amplitude * (w.k.dot(&p) + w.phase).cos())
        })
    }

    /// Triangulates the surface over `[min, max]` with square cells of about `cell` metres;
    /// `material(x, y)` chooses each triangle's material from its centroid.
    pub fn mesh(&self, min: [f64; 2], max: [f64; 2], cell: f64, material: impl Fn(f64, f64) -> Material) -> Mesh {
        let nx = ((max[0] - min[0]) / cell).ceil().max(1.0) as usize;
        let ny = ((max[1] - min[1]) / cell).ceil().max(1.0) as usize;
        let dx = (max[0] - min[0]) / nx as f64;
        let dy = (max[1] - min[1]) / ny as f64;
        let mut mesh = Mesh::new();
        mesh.vertices.reserve((nx + 1) * (ny + 1));
        for j in 0..=ny {
            for i in 0..=nx {
                let (x, y) = (min[0] + i as f64 * dx, min[1] + j as f64 * dy);
                mesh.push_vertex(Point3::new(x as f32, y as f32, self.height(x, y) as f32));
            }
        }
        let index = |i: usize, j: usize| (j * (nx + 1) + i) as u32;
        for j in 0..ny {
            for i in 0..nx {
                let m = material(min[0] + (i as f64 + 0.5) * dx, min[1] + (j as f64 + 0.5) * dy);
                let (a, b, c, d) = (index(i, j), index(i + 1, j), index(i + 1, j + 1), index(i, j + 1));
                mesh.push_triangle([a, b, c], m);
                mesh.push_triangle([a, c, d], m);
            }
        }
        mesh
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
            assert!((g.x - gx).abs() < 1e-7 && (g.y - gy).abs() < 1e-7, "gradient {g:?} vs ({gx}, {gy})");
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
        assert!(peak > 0.02 && peak < bound, "peak height {peak} should be non-zero and below {bound}");
    }
}
