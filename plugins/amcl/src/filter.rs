//! The particle filter: AMCL's Monte Carlo localisation with KLD-sampling and augmented
//! MCL's random particles, and its estimate.
//!
//! An update, as AMCL makes one on a laser scan: the first scan updates at once; later ones
//! only when the odometry has moved `update_min_d` along x or y or turned `update_min_a`
//! since the last update. Each particle is moved by the odometry's motion ([`OdomDelta`]),
//! weighted by the scan under the likelihood field, and every `resample_interval` updates
//! the set is resampled to as many particles as KLD-sampling asks for. The estimate, made
//! after each resampling, is the mean of the cluster of particles with the most weight; its
//! uncertainty the whole set's covariance, so while the set holds two competing places (two
//! lanes that look alike) the estimate does not count as localised. Resampling can drop one
//! of them (particle depletion), and then the filter is confident, right or wrong.
//!
//! Between updates the pose is the estimate moved by the odometry since (AMCL's `map` to
//! `odom` transform held fixed): [`ParticleFilter::pose_now`].

use std::collections::{BTreeMap, BTreeSet};

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};

use crate::config::AmclConfig;
use crate::grid::LikelihoodField;
use crate::motion::OdomDelta;
use crate::{Pose2, normalize};

/// The histogram's bin (KLD-sampling, clustering): 0.5 m x 0.5 m x 10°, AMCL's.
const BIN_M: f64 = 0.5;
const BIN_RAD: f64 = std::f64::consts::PI / 18.0;

/// One hypothesis.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Particle {
    pub pose: Pose2,
    pub weight: f64,
}

/// The filter's answer.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Estimate {
    /// The mean of the heaviest cluster, `map_from_base`.
    pub pose: Pose2,
    /// The whole set's variances: x, y (m²) and heading (rad², from the mean resultant
    /// length: -2 ln R).
    pub var_x: f64,
    pub var_y: f64,
    pub var_theta: f64,
    /// Clusters in the set, and the heaviest one's share of the weight.
    pub clusters: usize,
    pub weight: f64,
    /// The set's spread within AMCL's diagnostic levels (`std_warn_level_*`).
    pub localized: bool,
}

/// AMCL's filter over one map.
#[derive(Debug, Clone)]
pub struct ParticleFilter {
    cfg: AmclConfig,
    particles: Vec<Particle>,
    w_slow: f64,
    w_fast: f64,
    rng: ChaCha8Rng,
    /// The odometry at the last update (`None` before the first).
    last_update_odom: Option<Pose2>,
    updates: usize,
    estimate: Estimate,
    /// `map_from_odom` as of the last estimate.
    map_from_odom: Pose2,
}

impl ParticleFilter {
    /// Global localisation: `max_particles` particles on random free cells with random
    /// headings (AMCL's `global_localization`).
    pub fn global(cfg: AmclConfig, field: &LikelihoodField) -> Result<Self, String> {
        cfg.validate()?;
        let mut rng = ChaCha8Rng::seed_from_u64(cfg.seed);
        let n = cfg.max_particles;
        let mut particles = Vec::with_capacity(n);
        for _ in 0..n {
            let pose = field
                .random_free_pose(&mut rng)
                .ok_or("the map has no free cell to place particles on")?;
            particles.push(Particle {
                pose,
                weight: 1.0 / n as f64,
            });
        }
        Ok(Self::with(cfg, particles, rng))
    }

    /// Localisation from a guess: `max_particles` particles drawn around `mean` with the
    /// configured initial covariance (AMCL's initial pose).
    pub fn at(cfg: AmclConfig, mean: Pose2) -> Result<Self, String> {
        cfg.validate()?;
        let mut rng = ChaCha8Rng::seed_from_u64(cfg.seed);
        let n = cfg.max_particles;
        let normal = |var: f64| Normal::new(0.0, var.sqrt()).expect("finite variance");
        let (nx, ny, na) = (
            normal(cfg.initial_cov_xx),
            normal(cfg.initial_cov_yy),
            normal(cfg.initial_cov_aa),
        );
        let particles = (0..n)
            .map(|_| Particle {
                pose: Pose2::new(
                    mean.x + nx.sample(&mut rng),
                    mean.y + ny.sample(&mut rng),
                    mean.theta + na.sample(&mut rng),
                ),
                weight: 1.0 / n as f64,
            })
            .collect();
        Ok(Self::with(cfg, particles, rng))
    }

    fn with(cfg: AmclConfig, particles: Vec<Particle>, rng: ChaCha8Rng) -> Self {
        let estimate = estimate(&particles, &cfg);
        Self {
            cfg,
            particles,
            w_slow: 0.0,
            w_fast: 0.0,
            rng,
            last_update_odom: None,
            updates: 0,
            map_from_odom: estimate.pose,
            estimate,
        }
    }

    pub fn particles(&self) -> &[Particle] {
        &self.particles
    }

    pub fn estimate(&self) -> &Estimate {
        &self.estimate
    }

    /// `map_from_base` at odometry pose `odom`: the last estimate moved by the odometry
    /// since.
    pub fn pose_now(&self, odom: &Pose2) -> Pose2 {
        self.map_from_odom.compose(odom)
    }

    /// A scan at odometry pose `odom` (`odom_from_base`): `beams` are every beam's end point
    /// in the base frame, `None` for a beam without a return within `range_max`. Returns
    /// whether the filter updated (moved enough, or the first scan).
    pub fn update(
        &mut self,
        odom: &Pose2,
        beams: &[Option<[f64; 2]>],
        range_max: f64,
        field: &LikelihoodField,
    ) -> bool {
        match self.last_update_odom {
            None => {}
            Some(last) => {
                let moved = (odom.x - last.x).abs() > self.cfg.update_min_d
                    || (odom.y - last.y).abs() > self.cfg.update_min_d
                    || normalize(odom.theta - last.theta).abs() > self.cfg.update_min_a;
                if !moved {
                    return false;
                }
                let delta = OdomDelta::between(&last, odom);
                let alphas = [
                    self.cfg.odom_alpha1,
                    self.cfg.odom_alpha2,
                    self.cfg.odom_alpha3,
                    self.cfg.odom_alpha4,
                ];
                for p in &mut self.particles {
                    p.pose = delta.sample(&p.pose, self.cfg.odom_model_type, alphas, &mut self.rng);
                }
            }
        }
        let first = self.last_update_odom.is_none();
        self.last_update_odom = Some(*odom);
        self.weigh(beams, range_max, field);
        self.updates += 1;
        if self.updates % self.cfg.resample_interval == 0 {
            self.resample(field);
        }
        if first || self.updates % self.cfg.resample_interval == 0 {
            // AMCL publishes its estimate after a resampling (and on the first scan).
            self.estimate = estimate(&self.particles, &self.cfg);
            self.map_from_odom = self.estimate.pose.compose(&odom.inverse());
        }
        true
    }

    /// The likelihood-field weights (Probabilistic Robotics §6.4) as AMCL combines them: per
    /// particle `1 + Σ pz³` over every `step`-th beam, `pz = z_hit exp(-d²/2σ²) + z_rand /
    /// range_max` with `d` the end point's distance to the nearest obstacle (AMCL's own
    /// "ad-hoc weighting scheme" in place of the product). Then augmented MCL's long- and
    /// short-term averages of the weights (§8.3.5).
    fn weigh(&mut self, beams: &[Option<[f64; 2]>], range_max: f64, field: &LikelihoodField) {
        let c = &self.cfg;
        let step = ((beams.len().max(1) - 1) / (c.laser_max_beams - 1)).max(1);
        let used: Vec<[f64; 2]> = beams.iter().step_by(step).flatten().copied().collect();
        let denominator = 2.0 * c.laser_sigma_hit * c.laser_sigma_hit;
        let z_rand = if range_max > 0.0 {
            c.laser_z_rand / range_max
        } else {
            0.0
        };
        let mut total = 0.0;
        for p in &mut self.particles {
            let mut likelihood = 1.0;
            for end in &used {
                let [x, y] = p.pose.transform(*end);
                let d = field.distance_at(x, y);
                let pz = c.laser_z_hit * (-d * d / denominator).exp() + z_rand;
                likelihood += pz * pz * pz;
            }
            p.weight *= likelihood;
            total += p.weight;
        }
        let n = self.particles.len() as f64;
        if total > 0.0 && total.is_finite() {
            let w_avg = total / n;
            for p in &mut self.particles {
                p.weight /= total;
            }
            self.w_slow = if self.w_slow == 0.0 {
                w_avg
            } else {
                self.w_slow + c.recovery_alpha_slow * (w_avg - self.w_slow)
            };
            self.w_fast = if self.w_fast == 0.0 {
                w_avg
            } else {
                self.w_fast + c.recovery_alpha_fast * (w_avg - self.w_fast)
            };
        } else {
            for p in &mut self.particles {
                p.weight = 1.0 / n;
            }
        }
    }

    /// KLD-sampling (Fox 2003) with augmented MCL's random particles: draw from the weighted
    /// set (a random free pose instead with probability `max(0, 1 - w_fast / w_slow)`),
    /// counting the histogram's occupied bins, until as many particles as the KLD bound for
    /// that many bins (or `max_particles`).
    fn resample(&mut self, field: &LikelihoodField) {
        let mut cumulative = Vec::with_capacity(self.particles.len());
        let mut sum = 0.0;
        for p in &self.particles {
            sum += p.weight;
            cumulative.push(sum);
        }
        let w_diff = if self.w_slow > 0.0 {
            (1.0 - self.w_fast / self.w_slow).max(0.0)
        } else {
            0.0
        };
        let mut bins = BTreeSet::new();
        let mut out = Vec::new();
        while out.len() < self.cfg.max_particles {
            let pose = match (self.rng.random::<f64>() < w_diff)
                .then(|| field.random_free_pose(&mut self.rng))
                .flatten()
            {
                Some(random) => random,
                None => {
                    let r = self.rng.random::<f64>() * sum;
                    let k = cumulative
                        .partition_point(|&c| c < r)
                        .min(cumulative.len() - 1);
                    self.particles[k].pose
                }
            };
            out.push(Particle { pose, weight: 1.0 });
            bins.insert(bin_of(&pose));
            if out.len() > kld_limit(bins.len(), &self.cfg) {
                break;
            }
        }
        if w_diff > 0.0 {
            self.w_slow = 0.0;
            self.w_fast = 0.0;
        }
        let n = out.len() as f64;
        for p in &mut out {
            p.weight = 1.0 / n;
        }
        self.particles = out;
    }
}

/// The histogram bin of a pose.
fn bin_of(p: &Pose2) -> (i64, i64, i64) {
    (
        (p.x / BIN_M).floor() as i64,
        (p.y / BIN_M).floor() as i64,
        (p.theta / BIN_RAD).floor() as i64,
    )
}

/// Fox's KLD bound for `k` occupied bins, `n = ⌈(k-1)/(2ε) (1 - 2/(9(k-1)) + √(2/(9(k-1))) z)³⌉`,
/// within [`min_particles`, `max_particles`]; `z` is AMCL's `kld_z` as given (AMCL puts it
/// into the formula itself rather than the normal quantile it names).
pub fn kld_limit(k: usize, cfg: &AmclConfig) -> usize {
    if k <= 1 {
        return cfg.max_particles;
    }
    let k1 = (k - 1) as f64;
    let b = 2.0 / (9.0 * k1);
    let x = 1.0 - b + b.sqrt() * cfg.kld_z;
    let n = (k1 / (2.0 * cfg.kld_err) * x * x * x).ceil() as usize;
    n.clamp(cfg.min_particles, cfg.max_particles)
}

/// The estimate of a set: clusters of particles in neighbouring bins (the 26 around a bin),
/// the heaviest cluster's weighted mean pose, the whole set's spread.
fn estimate(particles: &[Particle], cfg: &AmclConfig) -> Estimate {
    let mut bins: BTreeMap<(i64, i64, i64), Vec<usize>> = BTreeMap::new();
    for (i, p) in particles.iter().enumerate() {
        bins.entry(bin_of(&p.pose)).or_default().push(i);
    }
    // Connected components over the occupied bins.
    let mut label: BTreeMap<(i64, i64, i64), usize> = BTreeMap::new();
    let mut clusters = 0;
    for &start in bins.keys() {
        if label.contains_key(&start) {
            continue;
        }
        let mut stack = vec![start];
        label.insert(start, clusters);
        while let Some((x, y, t)) = stack.pop() {
            for dx in -1..=1 {
                for dy in -1..=1 {
                    for dt in -1..=1 {
                        let n = (x + dx, y + dy, t + dt);
                        if bins.contains_key(&n) && !label.contains_key(&n) {
                            label.insert(n, clusters);
                            stack.push(n);
                        }
                    }
                }
            }
        }
        clusters += 1;
    }
    // Per cluster: weight, weighted sums of x, y, cos, sin.
    let mut sums = vec![[0.0f64; 5]; clusters];
    let mut all = [0.0f64; 8];
    for (key, members) in &bins {
        let c = label[key];
        for &i in members {
            let p = &particles[i];
            let w = p.weight;
            let (s, co) = p.pose.theta.sin_cos();
            let cluster = &mut sums[c];
            cluster[0] += w;
            cluster[1] += w * p.pose.x;
            cluster[2] += w * p.pose.y;
            cluster[3] += w * co;
            cluster[4] += w * s;
            all[0] += w;
            all[1] += w * p.pose.x;
            all[2] += w * p.pose.y;
            all[3] += w * co;
            all[4] += w * s;
            all[5] += w * p.pose.x * p.pose.x;
            all[6] += w * p.pose.y * p.pose.y;
        }
    }
    let heaviest = sums
        .iter()
        .enumerate()
        .max_by(|a, b| a.1[0].total_cmp(&b.1[0]).then(b.0.cmp(&a.0)))
        .map(|(i, _)| i);
    let total = all[0];
    let (pose, weight) = match heaviest {
        Some(c) if sums[c][0] > 0.0 => {
            let s = sums[c];
            (
                Pose2::new(s[1] / s[0], s[2] / s[0], s[4].atan2(s[3])),
                s[0] / total,
            )
        }
        _ => (Pose2::default(), 0.0),
    };
    let (var_x, var_y, var_theta) = if total > 0.0 {
        let (mx, my) = (all[1] / total, all[2] / total);
        let r = (all[3] * all[3] + all[4] * all[4]).sqrt() / total;
        (
            (all[5] / total - mx * mx).max(0.0),
            (all[6] / total - my * my).max(0.0),
            if r > 0.0 {
                -2.0 * r.min(1.0).ln()
            } else {
                f64::INFINITY
            },
        )
    } else {
        (f64::INFINITY, f64::INFINITY, f64::INFINITY)
    };
    Estimate {
        pose,
        var_x,
        var_y,
        var_theta,
        clusters,
        weight,
        localized: var_x.sqrt() <= cfg.std_warn_level_x
            && var_y.sqrt() <= cfg.std_warn_level_y
            && var_theta.sqrt() <= cfg.std_warn_level_yaw,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::grid::{Grid, Occupancy};

    /// A 12 m x 8 m room at 0.1 m: walls, and blocks placed so that no rotation or mirror
    /// maps the room onto itself.
    fn asymmetric_room() -> LikelihoodField {
        // A crate near the south-west, a wall stub in the north-east, a short wall from the
        // south wall.
        walled_room(&[(20, 20, 30, 25), (80, 50, 83, 70), (50, 0, 52, 15)])
    }

    /// A 12 m x 8 m room at 0.1 m, walled, with `blocks` of cells `(i0, j0, i1, j1)`
    /// (ends excluded) occupied.
    fn walled_room(blocks: &[(usize, usize, usize, usize)]) -> LikelihoodField {
        let (w, h) = (120, 80);
        let walls = [
            (0, 0, w, 1),
            (0, h - 1, w, h),
            (0, 0, 1, h),
            (w - 1, 0, w, h),
        ];
        let mut cells = vec![0i8; w * h];
        for &(i0, j0, i1, j1) in walls.iter().chain(blocks) {
            for j in j0..j1 {
                for i in i0..i1 {
                    cells[j * w + i] = 100;
                }
            }
        }
        LikelihoodField::new(Grid::new(0.1, [0.0, 0.0], w, h, cells).expect("grid"), 2.0)
    }

    /// A 360-beam scan from `pose` (base = sensor), ray-marched in the grid to 10 m.
    fn scan(field: &LikelihoodField, pose: &Pose2) -> Vec<Option<[f64; 2]>> {
        (0..360)
            .map(|k| {
                let a = (k as f64).to_radians();
                let mut r = 0.0;
                while r < 10.0 {
                    r += 0.02;
                    let [x, y] = pose.transform([r * a.cos(), r * a.sin()]);
                    match field.grid.cell_of(x, y) {
                        Some((i, j)) if field.grid.occupancy(i, j) == Occupancy::Occupied => {
                            return Some([r * a.cos(), r * a.sin()]);
                        }
                        None => return None,
                        _ => {}
                    }
                }
                None
            })
            .collect()
    }

    /// Drives a loop through the room, scanning every 0.1 m, and returns the filter.
    fn drive(
        mut filter: ParticleFilter,
        field: &LikelihoodField,
        steps: usize,
    ) -> (ParticleFilter, Pose2) {
        let mut truth = Pose2::new(4.0, 4.0, 0.0);
        for k in 0..steps {
            // Forward 0.1 m, turning left slowly: a circle of about 2.5 m radius.
            truth = truth.compose(&Pose2::new(0.1, 0.0, 0.04));
            let _ = k;
            // Odometry equals the truth here: the map's frame is the odometry's.
            filter.update(&truth, &scan(field, &truth), 10.0, field);
        }
        (filter, truth)
    }

    #[test]
    fn from_a_guess_it_tracks_the_robot_and_says_it_is_localised() {
        let field = asymmetric_room();
        let start = Pose2::new(4.0, 4.0, 0.0);
        let filter = ParticleFilter::at(AmclConfig::default(), start).expect("valid");
        assert!(
            !filter.estimate().localized,
            "0.5 m σ at the start is above 0.2 m"
        );
        let (filter, truth) = drive(filter, &field, 120);
        let e = filter.estimate();
        let error = (e.pose.x - truth.x).hypot(e.pose.y - truth.y);
        // Within half a histogram bin (0.25 m) and 0.1 rad (AMCL's `std_warn_level_yaw`).
        assert!(error < 0.25, "{e:?} vs {truth:?}");
        assert!(normalize(e.pose.theta - truth.theta).abs() < 0.1, "{e:?}");
        assert!(e.localized, "{e:?}");
        assert!(
            filter.particles().len() < 1000,
            "KLD-sampling shrinks the set once it has converged: {}",
            filter.particles().len()
        );
    }

    #[test]
    fn from_nowhere_it_finds_the_robot_in_an_asymmetric_room() {
        let field = asymmetric_room();
        let filter = ParticleFilter::global(AmclConfig::default(), &field).expect("valid");
        assert!(!filter.estimate().localized);
        let (filter, truth) = drive(filter, &field, 150);
        let e = filter.estimate();
        let error = (e.pose.x - truth.x).hypot(e.pose.y - truth.y);
        assert!(error < 0.25, "{e:?} vs {truth:?}");
        assert!(e.localized, "{e:?}");
    }

    /// Two places that look the same (a room that a half turn maps onto itself, as two
    /// lanes of identical rows): where the filter says it is localised it is at one of
    /// the two, and which one is chance: over eight seeds it is the wrong one in some.
    /// The confident wrong-lane localisation that issue 46's metrics count.
    #[test]
    fn where_two_places_look_alike_it_commits_to_one_right_or_wrong() {
        // Two crates, each the other's image under the half turn about the centre.
        let field = walled_room(&[(20, 20, 30, 25), (90, 55, 100, 60)]);
        // Per seed: confidently at the truth, confidently at its image, or not localised.
        let mut outcomes = [0; 3];
        for seed in 0..8 {
            let cfg = AmclConfig {
                seed,
                ..AmclConfig::default()
            };
            let start = ParticleFilter::global(cfg, &field).expect("valid");
            let (f, truth) = drive(start, &field, 150);
            let e = f.estimate();
            let image = Pose2::new(
                12.0 - truth.x,
                8.0 - truth.y,
                truth.theta + std::f64::consts::PI,
            );
            let on = |p: &Pose2| (e.pose.x - p.x).hypot(e.pose.y - p.y) < 0.3;
            assert!(
                !e.localized || on(&truth) || on(&image),
                "seed {seed}: localised {e:?} at neither {truth:?} nor its image"
            );
            outcomes[match (e.localized, on(&truth)) {
                (true, true) => 0,
                (true, false) => 1,
                (false, _) => 2,
            }] += 1;
        }
        eprintln!("truth, image, undecided: {outcomes:?}");
        assert!(outcomes[1] > 0, "never confidently wrong: {outcomes:?}");
        assert!(outcomes[0] > 0, "never confidently right: {outcomes:?}");
    }

    #[test]
    fn it_does_not_update_until_the_odometry_has_moved_enough() {
        let field = asymmetric_room();
        let start = Pose2::new(4.0, 4.0, 0.0);
        let mut f = ParticleFilter::at(AmclConfig::default(), start).expect("valid");
        assert!(
            f.update(&start, &scan(&field, &start), 10.0, &field),
            "the first scan"
        );
        let near = Pose2::new(4.15, 4.1, 0.4);
        assert!(
            !f.update(&near, &scan(&field, &near), 10.0, &field),
            "0.15 m, 0.4 rad"
        );
        let far = Pose2::new(4.25, 4.0, 0.0);
        assert!(
            f.update(&far, &scan(&field, &far), 10.0, &field),
            "0.25 m along x"
        );
        // Between updates the pose follows the odometry: 1 m driven is 1 m in the map, in
        // the direction the estimate faces.
        let p = f.pose_now(&Pose2::new(5.0, 4.0, 0.0));
        let q = f.pose_now(&Pose2::new(4.0, 4.0, 0.0));
        assert!(((p.x - q.x).hypot(p.y - q.y) - 1.0).abs() < 1e-9);
        let heading = (p.y - q.y).atan2(p.x - q.x);
        assert!(normalize(heading - q.theta).abs() < 1e-9);
    }

    #[test]
    fn the_kld_bound_is_foxs_with_amcls_z() {
        let cfg = AmclConfig {
            min_particles: 1,
            ..AmclConfig::default()
        };
        assert_eq!(kld_limit(1, &cfg), 5000, "one bin: as many as allowed");
        // k = 2: 50 (1 - 2/9 + √(2/9) 0.99)³ = 96.37.
        assert_eq!(kld_limit(2, &cfg), 97);
        // k = 101: 5000 (1 - 2/900 + √(2/900) 0.99)³ = 5664 → the maximum.
        assert_eq!(kld_limit(101, &cfg), 5000);
        assert_eq!(
            kld_limit(2, &AmclConfig::default()),
            100,
            "at least min_particles"
        );
    }

    #[test]
    fn the_same_seed_gives_the_same_particles() {
        let field = asymmetric_room();
        let run = || {
            let f = ParticleFilter::global(AmclConfig::default(), &field).expect("valid");
            drive(f, &field, 20).0.particles().to_vec()
        };
        assert_eq!(run(), run());
    }
}
