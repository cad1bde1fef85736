//! Scan Context: an egocentric polar descriptor of a 3D lidar scan for place recognition,
//! which also gives the heading between two scans of one place (Kim & Kim, "Scan Context:
//! Egocentric Spatial Descriptor for Place Recognition within 3D Point Cloud Map", IROS
//! 2018), for a global search over a map's keyframes before registration verifies it.
//!
//! The method, as published and as its authors' C++ (`gisbi-kim/scancontext`,
//! `Scancontext.h`) sets it:
//! - the plane around the sensor is cut into `rings` annuli out to `max_radius_m` and
//!   `sectors` wedges; a cell holds the highest point in it (z plus `lidar_height_m`, so that
//!   every height is above 0 and an empty cell, 0, is lower than any return);
//! - two descriptors' distance is one minus the mean cosine similarity of their columns
//!   (sectors), over the columns where both have a return, minimised over circular shifts of
//!   the columns: the best shift is the heading between the two scans. The shifts tried are
//!   those within `search_ratio / 2` of the shift that best aligns the two sector keys (each
//!   column's mean);
//! - a database is searched by the ring key (each ring's mean, invariant to heading) for
//!   the `candidates` nearest keyframes, the most recent `exclude_recent` excluded; the
//!   candidate at the least distance is a match when under `distance_threshold`.
//!
//! Defaults: the C++'s (20 rings, 60 sectors, 80 m, 2.0 m, search ratio 0.1, 10
//! candidates, threshold 0.13, 50 excluded). The ring keys are searched exhaustively (the C++
//! uses a k-d tree, an exact search too, rebuilt every 50 queries).

use serde::Deserialize;

/// Scan Context's parameters.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct ScanContextConfig {
    pub rings: usize,
    pub sectors: usize,
    pub max_radius_m: f64,
    pub lidar_height_m: f64,
    pub search_ratio: f64,
    pub candidates: usize,
    pub distance_threshold: f64,
    pub exclude_recent: usize,
}

impl Default for ScanContextConfig {
    fn default() -> Self {
        Self {
            rings: 20,
            sectors: 60,
            max_radius_m: 80.0,
            lidar_height_m: 2.0,
            search_ratio: 0.1,
            candidates: 10,
            distance_threshold: 0.13,
            exclude_recent: 50,
        }
    }
}

/// One scan's descriptor: `rings` x `sectors` cells, row-major by ring.
#[derive(Debug, Clone, PartialEq)]
pub struct ScanContext {
    rings: usize,
    sectors: usize,
    cells: Vec<f32>,
}

impl ScanContext {
    /// The descriptor of a scan's points, in the sensor's frame (x forward, z up).
    pub fn new(points: &[[f32; 3]], cfg: &ScanContextConfig) -> Self {
        let (rings, sectors) = (cfg.rings, cfg.sectors);
        let mut cells = vec![0.0f32; rings * sectors];
        let ring_gap = cfg.max_radius_m / rings as f64;
        let sector_angle = std::f64::consts::TAU / sectors as f64;
        for p in points {
            let (x, y) = (f64::from(p[0]), f64::from(p[1]));
            let r = x.hypot(y);
            if !p.iter().all(|v| v.is_finite()) || r >= cfg.max_radius_m {
                continue;
            }
            let azimuth = y.atan2(x).rem_euclid(std::f64::consts::TAU);
            let ring = ((r / ring_gap) as usize).min(rings - 1);
            let sector = ((azimuth / sector_angle) as usize).min(sectors - 1);
            let z = (f64::from(p[2]) + cfg.lidar_height_m) as f32;
            let cell = &mut cells[ring * sectors + sector];
            *cell = cell.max(z);
        }
        Self {
            rings,
            sectors,
            cells,
        }
    }

    fn cell(&self, ring: usize, sector: usize) -> f32 {
        self.cells[ring * self.sectors + sector]
    }

    /// Each ring's mean: the same whatever the heading.
    pub fn ring_key(&self) -> Vec<f32> {
        (0..self.rings)
            .map(|r| (0..self.sectors).map(|s| self.cell(r, s)).sum::<f32>() / self.sectors as f32)
            .collect()
    }

    /// Each sector's mean.
    fn sector_key(&self) -> Vec<f32> {
        (0..self.sectors)
            .map(|s| (0..self.rings).map(|r| self.cell(r, s)).sum::<f32>() / self.rings as f32)
            .collect()
    }

    /// The distance at one shift: `1 - mean cos(column j of self, column j + shift of
    /// other)` over the columns where both have a return (1 where there is none).
    fn distance_at(&self, other: &ScanContext, shift: usize) -> f64 {
        let mut sum = 0.0;
        let mut columns = 0;
        for j in 0..self.sectors {
            let k = (j + shift) % self.sectors;
            let (mut dot, mut na, mut nb) = (0.0f64, 0.0f64, 0.0f64);
            for r in 0..self.rings {
                let (a, b) = (f64::from(self.cell(r, j)), f64::from(other.cell(r, k)));
                dot += a * b;
                na += a * a;
                nb += b * b;
            }
            if na > 0.0 && nb > 0.0 {
                sum += dot / (na.sqrt() * nb.sqrt());
                columns += 1;
            }
        }
        if columns == 0 {
            1.0
        } else {
            1.0 - sum / columns as f64
        }
    }

    /// The distance to `other` (0: the same, up to 1) and the heading that aligns them,
    /// `other_from_self`'s yaw in radians (a multiple of the sector angle, in (-π, π]).
    pub fn distance(&self, other: &ScanContext, cfg: &ScanContextConfig) -> (f64, f64) {
        assert_eq!(
            (self.rings, self.sectors),
            (other.rings, other.sectors),
            "descriptors of one configuration"
        );
        let n = self.sectors;
        let (ka, kb) = (self.sector_key(), other.sector_key());
        // The shift that best aligns the sector keys (least L2 distance; ties: the least
        // shift).
        let coarse = (0..n)
            .map(|s| {
                let d: f64 = (0..n)
                    .map(|j| f64::from(ka[j] - kb[(j + s) % n]).powi(2))
                    .sum();
                (d, s)
            })
            .min_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)))
            .map_or(0, |(_, s)| s);
        let radius = (0.5 * cfg.search_ratio * n as f64).round() as i64;
        let (distance, shift) = (-radius..=radius)
            .map(|o| {
                let s = (coarse as i64 + o).rem_euclid(n as i64) as usize;
                (self.distance_at(other, s), s)
            })
            .min_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)))
            .expect("at least one shift");
        let mut yaw = shift as f64 * std::f64::consts::TAU / n as f64;
        if yaw > std::f64::consts::PI {
            yaw -= std::f64::consts::TAU;
        }
        (distance, yaw)
    }
}

/// A match in a [`ScanContextDatabase`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PlaceMatch {
    /// The index of the matched descriptor (in the order they were added).
    pub index: usize,
    pub distance: f64,
    /// `matched_from_query`'s yaw, radians.
    pub yaw_rad: f64,
}

/// The keyframes' descriptors, searched by ring key then by Scan Context distance.
#[derive(Debug, Clone, Default)]
pub struct ScanContextDatabase {
    cfg: ScanContextConfig,
    contexts: Vec<ScanContext>,
    ring_keys: Vec<Vec<f32>>,
}

impl ScanContextDatabase {
    pub fn new(cfg: ScanContextConfig) -> Self {
        Self {
            cfg,
            contexts: Vec::new(),
            ring_keys: Vec::new(),
        }
    }

    pub fn config(&self) -> &ScanContextConfig {
        &self.cfg
    }

    pub fn len(&self) -> usize {
        self.contexts.len()
    }

    pub fn is_empty(&self) -> bool {
        self.contexts.is_empty()
    }

    /// Adds a keyframe's descriptor; returns its index.
    pub fn add(&mut self, context: ScanContext) -> usize {
        self.ring_keys.push(context.ring_key());
        self.contexts.push(context);
        self.contexts.len() - 1
    }

    /// The best match of `query` among the descriptors but the last `exclude_recent` (for
    /// loop closure while mapping; 0 for localisation in a finished map), if under the
    /// threshold.
    pub fn search(&self, query: &ScanContext, exclude_recent: usize) -> Option<PlaceMatch> {
        let searchable = self.contexts.len().saturating_sub(exclude_recent);
        self.search_among(query, |i| i < searchable)
    }

    /// [`ScanContextDatabase::search`] over the places `allowed` keeps (a prior on where the
    /// query may be: a GNSS fix, say).
    pub fn search_among(
        &self,
        query: &ScanContext,
        allowed: impl Fn(usize) -> bool,
    ) -> Option<PlaceMatch> {
        let key = query.ring_key();
        let mut nearest: Vec<(f64, usize)> = (0..self.contexts.len())
            .filter(|&i| allowed(i))
            .map(|i| {
                let d: f64 = key
                    .iter()
                    .zip(&self.ring_keys[i])
                    .map(|(a, b)| f64::from(a - b).powi(2))
                    .sum();
                (d, i)
            })
            .collect();
        nearest.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
        nearest.truncate(self.cfg.candidates.max(1));
        nearest
            .into_iter()
            .map(|(_, i)| {
                let (distance, yaw_rad) = query.distance(&self.contexts[i], &self.cfg);
                PlaceMatch {
                    index: i,
                    distance,
                    yaw_rad,
                }
            })
            .min_by(|a, b| {
                a.distance
                    .total_cmp(&b.distance)
                    .then(a.index.cmp(&b.index))
            })
            .filter(|m| m.distance < self.cfg.distance_threshold)
    }
}

#[cfg(test)]
mod tests {
    use rand::{Rng, SeedableRng};

    use super::*;

    /// A place: `n` random pillars of random heights within 30 m, sampled as points.
    fn place(seed: u64) -> Vec<[f32; 3]> {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
        let mut points = Vec::new();
        for _ in 0..40 {
            let (r, a) = (
                rng.random_range(2.0..30.0f32),
                rng.random_range(0.0..std::f32::consts::TAU),
            );
            let h = rng.random_range(0.5..4.0f32);
            for k in 0..10 {
                points.push([r * a.cos(), r * a.sin(), -1.8 + h * k as f32 / 10.0]);
            }
        }
        points
    }

    fn rotated(points: &[[f32; 3]], yaw: f32) -> Vec<[f32; 3]> {
        let (s, c) = yaw.sin_cos();
        points
            .iter()
            .map(|p| [c * p[0] - s * p[1], s * p[0] + c * p[1], p[2]])
            .collect()
    }

    #[test]
    fn the_same_place_seen_turned_matches_with_its_heading() {
        let cfg = ScanContextConfig::default();
        let map = place(1);
        // The robot turned by ψ at the same place: it sees the world turned by -ψ.
        for psi_deg in [0.0f64, 30.0, -90.0, 150.0] {
            let psi = psi_deg.to_radians();
            let query = rotated(&map, -psi as f32);
            let (d, yaw) =
                ScanContext::new(&query, &cfg).distance(&ScanContext::new(&map, &cfg), &cfg);
            assert!(d < 0.05, "ψ {psi_deg}°: distance {d}");
            let error = (yaw - psi + std::f64::consts::PI).rem_euclid(std::f64::consts::TAU)
                - std::f64::consts::PI;
            assert!(
                error.abs() <= 6f64.to_radians(),
                "ψ {psi_deg}°: yaw {}°",
                yaw.to_degrees()
            );
        }
        // Another place is far.
        let (d, _) =
            ScanContext::new(&place(2), &cfg).distance(&ScanContext::new(&map, &cfg), &cfg);
        assert!(d > 0.3, "another place: {d}");
    }

    #[test]
    fn a_database_finds_the_place_and_refuses_an_unknown_one() {
        let cfg = ScanContextConfig::default();
        let mut db = ScanContextDatabase::new(cfg.clone());
        for seed in 10..30 {
            db.add(ScanContext::new(&place(seed), &cfg));
        }
        let query = ScanContext::new(&rotated(&place(17), 0.5), &cfg);
        let m = db.search(&query, 0).expect("a match");
        assert_eq!(m.index, 7);
        assert!(
            (m.yaw_rad + 0.5).abs() <= 6f64.to_radians(),
            "{}",
            m.yaw_rad
        );
        assert!(db.search(&ScanContext::new(&place(99), &cfg), 0).is_none());
        // Excluding the recent keyframes hides them.
        assert!(db.search(&query, 13).is_none());
    }
}
