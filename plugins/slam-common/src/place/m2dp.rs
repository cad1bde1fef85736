//! M2DP, the multiview 2D projection descriptor of a 3D point cloud, for lidar place
//! recognition: Li He, Xiaolong Wang and Hong Zhang, "M2DP: A Novel 3D Point Cloud
//! Descriptor and Its Application in Loop Closure Detection", IROS 2016. Written from the
//! paper and checked against the authors' MATLAB reference (`M2DP.m`, github.com/LiHeUA/M2DP).
//!
//! 1. The cloud is centred on its centroid and expressed in its principal axes: x the first
//!    principal component, y the second, z = x × y. The paper leaves the axes' signs open;
//!    here each of x and y points where the third moment (Σ (p·axis)³) of the cloud is
//!    positive (where it vanishes, where most points lie), so that the descriptor does not
//!    change when the cloud is rotated and translated.
//! 2. The cloud is projected onto `p · q` planes whose normals are
//!    m(θ, φ) = (cos φ cos θ, cos φ sin θ, sin φ), with `p` azimuths θ spread evenly over
//!    [−π/2, π/2] and `q` elevations φ spread evenly over [0, π/2], both ends included as the
//!    authors' code does (`linspace`; the paper: θ ∈ [−π/2, π/2], φ ∈ [0, π/2]). In a
//!    plane, the 2D x axis is the projection of the cloud's x axis (normalised; that of its y
//!    axis when m ∥ x), the 2D y axis is m × x. Coordinates keep their signs.
//! 3. Each projection is binned in polar coordinates: `t` sectors over [0, 2π) and `l` rings,
//!    the i-th circle of radius i²·r with r = ρ_max / l², ρ_max the largest distance of a point
//!    from the centroid. Each plane's counts make a row of the signature matrix A (pq × lt).
//! 4. The descriptor is [u₁; v₁], the first left and right singular vectors of A, signed so
//!    that v₁ sums to a positive number (A ≥ 0, so both are of one sign). Descriptors are
//!    compared by their L2 distance, as in the paper.
//!
//! With the paper's p = 4, q = 16, l = 8, t = 16: A is 64 × 128 and the descriptor has 192
//! values.
//!
//! StaticMapping (EdwardLiuyc/StaticMapping, `descriptor/m2dp.cc`) uses rings of a fixed
//! size in metres instead, and scores a match by the absolute Pearson correlation of the two
//! descriptors; [`Rings::Absolute`] and [`Descriptor::correlation`] reproduce those two
//! differences (not its folding of every projection into one quadrant, nor its swap of the
//! roles of θ and φ in the normal).

use std::f64::consts::{FRAC_PI_2, TAU};

use nalgebra::{DMatrix, Matrix3, SymmetricEigen, Vector3};

/// Fewer points than this give no descriptor.
pub const MIN_POINTS: usize = 10;

/// How the ring radii of the polar bins are chosen.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Rings {
    /// The paper: [`M2dpConfig::rings`] rings, the i-th circle of radius i²·ρ_max / l², so
    /// that the outermost reaches the farthest point from the centroid.
    Relative,
    /// StaticMapping: the i-th circle has radius i²·`ring_m`, points farther than
    /// `max_distance_m` from the centroid are dropped (after the principal axes are found
    /// from all of them, as StaticMapping does; the outermost ring takes any point beyond
    /// its circle), and the number of rings is
    /// ⌈√(`max_distance_m` / `ring_m`)⌉ ([`M2dpConfig::rings`] is ignored). StaticMapping's
    /// defaults, `ring_m` 0.1 and `max_distance_m` 100, give 32 rings.
    Absolute {
        /// The radius r of the innermost circle, metres.
        ring_m: f64,
        /// Points farther than this from the centroid are ignored, metres.
        max_distance_m: f64,
    },
}

/// Parameters of M2DP; the default is the paper's.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct M2dpConfig {
    /// Number p of azimuths θ of the projection planes' normals, over [−π/2, π/2] (4).
    pub azimuths: usize,
    /// Number q of elevations φ of the projection planes' normals, over [0, π/2] (16).
    pub elevations: usize,
    /// Number l of rings of the polar bins with [`Rings::Relative`] (8).
    pub rings: usize,
    /// Number t of angular sectors of the polar bins (16).
    pub sectors: usize,
    /// How the ring radii are chosen ([`Rings::Relative`], the paper's).
    pub radii: Rings,
}

impl Default for M2dpConfig {
    fn default() -> Self {
        Self {
            azimuths: 4,
            elevations: 16,
            rings: 8,
            sectors: 16,
            radii: Rings::Relative,
        }
    }
}

impl M2dpConfig {
    /// StaticMapping's configuration: the paper's planes and sectors, rings of 0.1 m (the
    /// i-th circle of radius 0.1·i² m) out to 100 m.
    pub fn static_mapping() -> Self {
        Self {
            radii: Rings::Absolute {
                ring_m: 0.1,
                max_distance_m: 100.0,
            },
            ..Self::default()
        }
    }

    /// Number of projection planes, p·q: the length of u₁.
    pub fn planes(&self) -> usize {
        self.azimuths * self.elevations
    }

    /// Number of rings l (computed from the ring size with [`Rings::Absolute`]), or `None`
    /// if the absolute ring parameters are not positive and finite.
    pub fn ring_count(&self) -> Option<usize> {
        match self.radii {
            Rings::Relative => Some(self.rings),
            Rings::Absolute {
                ring_m,
                max_distance_m,
            } => {
                let ok = ring_m.is_finite()
                    && ring_m > 1e-6
                    && max_distance_m.is_finite()
                    && max_distance_m > 0.0;
                ok.then(|| (max_distance_m / ring_m).sqrt().ceil() as usize)
            }
        }
    }

    /// Length of the descriptor: p·q + l·t.
    pub fn descriptor_len(&self) -> Option<usize> {
        Some(self.planes() + self.ring_count()? * self.sectors)
    }
}

/// An M2DP descriptor: the first left singular vector u₁ of the signature matrix (one
/// value per projection plane) followed by the first right singular vector v₁ (one value
/// per polar bin). Both halves have unit norm.
#[derive(Debug, Clone, PartialEq)]
pub struct Descriptor {
    /// [u₁; v₁].
    pub values: Vec<f64>,
    /// Number of projection planes: `values[..planes]` is u₁.
    pub planes: usize,
}

impl Descriptor {
    /// The first left singular vector, one value per projection plane.
    pub fn u1(&self) -> &[f64] {
        &self.values[..self.planes]
    }

    /// The first right singular vector, one value per polar bin.
    pub fn v1(&self) -> &[f64] {
        &self.values[self.planes..]
    }

    /// L2 distance between two descriptors, as the paper compares them: in [0, 2√2], 0 for
    /// the same place.
    ///
    /// # Panics
    /// If the descriptors have different lengths (different configurations).
    pub fn distance(&self, other: &Descriptor) -> f64 {
        self.check(other);
        self.values
            .iter()
            .zip(&other.values)
            .map(|(a, b)| (a - b).powi(2))
            .sum::<f64>()
            .sqrt()
    }

    /// Cosine similarity, dot / (|a| |b|), in [−1, 1]; with unit u₁ and v₁ it equals
    /// 1 − distance² / 4.
    ///
    /// # Panics
    /// If the descriptors have different lengths (different configurations).
    pub fn similarity(&self, other: &Descriptor) -> f64 {
        self.check(other);
        let dot: f64 = self
            .values
            .iter()
            .zip(&other.values)
            .map(|(a, b)| a * b)
            .sum();
        let norms = norm(&self.values) * norm(&other.values);
        if norms > 0.0 { dot / norms } else { 0.0 }
    }

    /// StaticMapping's match score: the absolute Pearson correlation of the two descriptors'
    /// values, |(N Σpq − Σp Σq) / √((N Σp² − (Σp)²)(N Σq² − (Σq)²))|, in [0, 1]; 0 when
    /// either descriptor is constant.
    ///
    /// # Panics
    /// If the descriptors have different lengths (different configurations).
    pub fn correlation(&self, other: &Descriptor) -> f64 {
        self.check(other);
        let n = self.values.len() as f64;
        let (p, q) = (&self.values, &other.values);
        let (sp, sq) = (p.iter().sum::<f64>(), q.iter().sum::<f64>());
        let spq: f64 = p.iter().zip(q).map(|(a, b)| a * b).sum();
        let spp: f64 = p.iter().map(|a| a * a).sum();
        let sqq: f64 = q.iter().map(|b| b * b).sum();
        let denominator = ((n * spp - sp * sp) * (n * sqq - sq * sq)).sqrt();
        if denominator > 0.0 {
            ((n * spq - sp * sq) / denominator).abs()
        } else {
            0.0
        }
    }

    fn check(&self, other: &Descriptor) {
        assert_eq!(
            (self.values.len(), self.planes),
            (other.values.len(), other.planes),
            "M2DP descriptors of different configurations"
        );
    }
}

fn norm(v: &[f64]) -> f64 {
    v.iter().map(|a| a * a).sum::<f64>().sqrt()
}

/// `n` values spread evenly over [lo, hi], both ends included (`lo` alone for n = 1).
fn spread(lo: f64, hi: f64, n: usize) -> impl Iterator<Item = f64> {
    (0..n).map(move |i| {
        if n == 1 {
            lo
        } else {
            lo + (hi - lo) * i as f64 / (n - 1) as f64
        }
    })
}

/// The M2DP descriptor of `points`, or `None` for fewer than [`MIN_POINTS`] (finite)
/// points, a degenerate cloud (all points on one line, so that its second principal axis
/// is undefined), a configuration with a zero count or invalid absolute rings.
///
/// The descriptor does not change when the cloud is rotated, translated or reordered,
/// unless its principal axes are ambiguous (two principal variances equal, or a vanishing
/// third moment along the first two axes, as in a cloud symmetric about them).
pub fn descriptor(points: &[Vector3<f64>], cfg: &M2dpConfig) -> Option<Descriptor> {
    let rings = cfg.ring_count()?;
    if cfg.azimuths == 0 || cfg.elevations == 0 || cfg.sectors == 0 || rings == 0 {
        return None;
    }
    let mut cloud = principal_frame(points)?;
    let ring_radius = match cfg.radii {
        Rings::Relative => {
            let max_rho = cloud.iter().map(|p| p.norm()).fold(0.0, f64::max);
            max_rho / (rings * rings) as f64
        }
        Rings::Absolute {
            ring_m,
            max_distance_m,
        } => {
            cloud.retain(|p| p.norm() <= max_distance_m);
            if cloud.len() < MIN_POINTS {
                return None;
            }
            ring_m
        }
    };
    if ring_radius <= 0.0 || !ring_radius.is_finite() {
        return None;
    }

    let bins = rings * cfg.sectors;
    let sector = TAU / cfg.sectors as f64;
    let mut a = DMatrix::<f64>::zeros(cfg.planes(), bins);
    let mut row = 0;
    for theta in spread(-FRAC_PI_2, FRAC_PI_2, cfg.azimuths) {
        for phi in spread(0.0, FRAC_PI_2, cfg.elevations) {
            let m = Vector3::new(phi.cos() * theta.cos(), phi.cos() * theta.sin(), phi.sin());
            let (px, py) = plane_axes(&m);
            for p in &cloud {
                let (u, v) = (p.dot(&px), p.dot(&py));
                let rho = u.hypot(v);
                let mut angle = v.atan2(u);
                if angle < 0.0 {
                    angle += TAU;
                }
                let s = ((angle / sector) as usize).min(cfg.sectors - 1);
                let r = ((rho / ring_radius).sqrt() as usize).min(rings - 1);
                a[(row, r * cfg.sectors + s)] += 1.0;
            }
            row += 1;
        }
    }

    let svd = a.svd(true, true);
    let (u, v_t) = (svd.u?, svd.v_t?);
    let first = svd.singular_values.iamax();
    if svd.singular_values[first] <= 0.0 {
        return None;
    }
    let mut u1: Vec<f64> = u.column(first).iter().copied().collect();
    let mut v1: Vec<f64> = v_t.row(first).iter().copied().collect();
    if v1.iter().sum::<f64>() < 0.0 {
        u1.iter_mut().for_each(|x| *x = -*x);
        v1.iter_mut().for_each(|x| *x = -*x);
    }
    u1.extend(v1);
    Some(Descriptor {
        values: u1,
        planes: cfg.planes(),
    })
}

/// The 2D axes of the plane with unit normal `m`: the projection of the cloud's x axis onto
/// the plane, normalised (that of its y axis when m ∥ x), and m × that.
fn plane_axes(m: &Vector3<f64>) -> (Vector3<f64>, Vector3<f64>) {
    let project = |e: Vector3<f64>| e - m * m.dot(&e);
    let mut px = project(Vector3::x());
    if px.norm() < 1e-9 {
        px = project(Vector3::y());
    }
    let px = px.normalize();
    (px, m.cross(&px))
}

/// The finite points of `points`, centred on their centroid and expressed in their
/// principal axes with deterministic signs; `None` if fewer than [`MIN_POINTS`] or on one
/// line.
fn principal_frame(points: &[Vector3<f64>]) -> Option<Vec<Vector3<f64>>> {
    let finite: Vec<&Vector3<f64>> = points
        .iter()
        .filter(|p| p.iter().all(|v| v.is_finite()))
        .collect();
    if finite.len() < MIN_POINTS {
        return None;
    }
    let n = finite.len() as f64;
    let centroid = finite.iter().copied().sum::<Vector3<f64>>() / n;
    let centred: Vec<Vector3<f64>> = finite.iter().map(|p| *p - centroid).collect();
    let cov = centred
        .iter()
        .map(|p| p * p.transpose())
        .sum::<Matrix3<f64>>()
        / n;
    let eig = SymmetricEigen::new(cov);
    let mut order = [0, 1, 2];
    order.sort_by(|&i, &j| eig.eigenvalues[j].total_cmp(&eig.eigenvalues[i]));
    let (l0, l1) = (eig.eigenvalues[order[0]], eig.eigenvalues[order[1]]);
    if l0.is_nan() || l0 <= 0.0 || l1 <= 1e-12 * l0 {
        return None;
    }
    let x = oriented(&centred, eig.eigenvectors.column(order[0]).normalize());
    let y = oriented(&centred, eig.eigenvectors.column(order[1]).normalize());
    let z = x.cross(&y);
    Some(
        centred
            .iter()
            .map(|p| Vector3::new(p.dot(&x), p.dot(&y), p.dot(&z)))
            .collect(),
    )
}

/// `axis` or its opposite: the one along which the cloud's third moment is positive, or,
/// if that vanishes, along which more points lie on the positive side.
fn oriented(centred: &[Vector3<f64>], axis: Vector3<f64>) -> Vector3<f64> {
    let (mut third, mut scale, mut balance) = (0.0, 0.0, 0i64);
    for p in centred {
        let d = p.dot(&axis);
        third += d * d * d;
        scale += d.abs().powi(3);
        balance += i64::from(d > 0.0) - i64::from(d < 0.0);
    }
    let flip = if third.abs() > 1e-9 * scale {
        third < 0.0
    } else {
        balance < 0
    };
    if flip { -axis } else { axis }
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::{Translation3, UnitQuaternion};
    use rand::seq::SliceRandom;
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;
    use std::f64::consts::PI;

    /// A posts, and a wall, of the given sizes, on a sloped ground.
    struct Scene {
        slope: (f64, f64),
        /// (x, y, radius, height)
        posts: Vec<(f64, f64, f64, f64)>,
        /// x of the wall, its y extent and height
        wall: (f64, (f64, f64), f64),
    }

    fn scene_a() -> Scene {
        Scene {
            slope: (0.05, -0.02),
            posts: vec![
                (3.0, 2.0, 0.10, 1.5),
                (-4.0, 5.0, 0.15, 2.5),
                (6.0, -3.0, 0.08, 3.2),
            ],
            wall: (9.0, (-6.0, 2.0), 2.4),
        }
    }

    fn scene_b() -> Scene {
        Scene {
            slope: (-0.03, 0.04),
            posts: vec![
                (-2.0, -4.0, 0.2, 2.0),
                (1.0, 6.0, 0.1, 1.2),
                (-7.0, 1.0, 0.12, 2.8),
                (5.0, 5.0, 0.1, 1.8),
            ],
            wall: (-9.0, (-2.0, 7.0), 1.6),
        }
    }

    fn cloud(scene: &Scene, seed: u64) -> Vec<Vector3<f64>> {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let ground = |x: f64, y: f64| scene.slope.0 * x + scene.slope.1 * y;
        let mut points = Vec::new();
        for _ in 0..3000 {
            let (x, y) = (rng.random_range(-10.0..12.0), rng.random_range(-8.0..9.0));
            points.push(Vector3::new(x, y, ground(x, y)));
        }
        for &(px, py, radius, height) in &scene.posts {
            for _ in 0..250 {
                let a: f64 = rng.random_range(0.0..TAU);
                let h = rng.random_range(0.0..height);
                let (x, y) = (px + radius * a.cos(), py + radius * a.sin());
                points.push(Vector3::new(x, y, ground(px, py) + h));
            }
        }
        let (wx, (y0, y1), height) = scene.wall;
        for _ in 0..800 {
            let y = rng.random_range(y0..y1);
            let h = rng.random_range(0.0..height);
            points.push(Vector3::new(wx, y, ground(wx, y) + h));
        }
        points
    }

    fn max_abs_difference(a: &Descriptor, b: &Descriptor) -> f64 {
        assert_eq!(a.values.len(), b.values.len());
        a.values
            .iter()
            .zip(&b.values)
            .map(|(x, y)| (x - y).abs())
            .fold(0.0, f64::max)
    }

    fn moved(
        points: &[Vector3<f64>],
        rpy: (f64, f64, f64),
        t: [f64; 3],
        seed: u64,
    ) -> Vec<Vector3<f64>> {
        let pose = nalgebra::Isometry3::from_parts(
            Translation3::new(t[0], t[1], t[2]),
            UnitQuaternion::from_euler_angles(rpy.0, rpy.1, rpy.2),
        );
        let mut out: Vec<Vector3<f64>> = points
            .iter()
            .map(|p| (pose * nalgebra::Point3::from(*p)).coords)
            .collect();
        out.shuffle(&mut ChaCha8Rng::seed_from_u64(seed));
        out
    }

    /// Guards the sign conventions of the PCA frame and of the singular vectors: the cloud
    /// rotated about all three axes (including half turns, which flip principal axes),
    /// translated and shuffled has the same descriptor, for both ring layouts.
    #[test]
    fn m2dp_is_invariant_to_rotation_translation_and_order() {
        let points = cloud(&scene_a(), 1);
        for cfg in [M2dpConfig::default(), M2dpConfig::static_mapping()] {
            let d = descriptor(&points, &cfg).expect("a descriptor");
            for (k, (rpy, t)) in [
                ((0.3, -0.7, 2.1), [12.0, -40.0, 3.0]),
                ((PI, 0.0, 0.0), [0.0, 0.0, 0.0]),
                ((0.0, 0.0, PI), [-5.0, 2.0, 0.5]),
                ((1.2, 2.9, -2.5), [100.0, 200.0, -30.0]),
            ]
            .into_iter()
            .enumerate()
            {
                let other =
                    descriptor(&moved(&points, rpy, t, k as u64), &cfg).expect("a descriptor");
                let diff = max_abs_difference(&d, &other);
                assert!(
                    diff < 1e-6,
                    "{cfg:?}, rotation {rpy:?}: values differ by {diff}"
                );
            }
        }
    }

    /// Guards the layout: 192 values with the paper's parameters, u₁ (64) and v₁ (128) of
    /// unit norm and of one (positive) sign, as singular vectors of a non-negative matrix.
    #[test]
    fn m2dp_has_192_values_in_two_unit_halves() {
        let d = descriptor(&cloud(&scene_a(), 2), &M2dpConfig::default()).expect("a descriptor");
        assert_eq!(d.values.len(), 192);
        assert_eq!(M2dpConfig::default().descriptor_len(), Some(192));
        assert_eq!((d.u1().len(), d.v1().len()), (64, 128));
        for half in [d.u1(), d.v1()] {
            assert!((norm(half) - 1.0).abs() < 1e-9, "norm {}", norm(half));
            assert!(half.iter().all(|&x| x >= -1e-9), "one sign: {half:?}");
        }
        assert!((d.similarity(&d) - 1.0).abs() < 1e-12);
        assert!(d.distance(&d) < 1e-12);
    }

    /// Guards that the descriptor tells places apart: 1 cm of noise on every point moves it
    /// much less than another scene does, and similarity agrees with distance.
    #[test]
    fn m2dp_separates_scenes_more_than_noise() {
        let cfg = M2dpConfig::default();
        let a_points = cloud(&scene_a(), 3);
        let a = descriptor(&a_points, &cfg).expect("a descriptor");
        let mut rng = ChaCha8Rng::seed_from_u64(4);
        let noisy: Vec<Vector3<f64>> = a_points
            .iter()
            .map(|p| {
                p + Vector3::new(
                    rng.random_range(-0.01..0.01),
                    rng.random_range(-0.01..0.01),
                    rng.random_range(-0.01..0.01),
                )
            })
            .collect();
        let a_noisy = descriptor(&noisy, &cfg).expect("a descriptor");
        let b = descriptor(&cloud(&scene_b(), 3), &cfg).expect("a descriptor");
        let (same, different) = (a.distance(&a_noisy), a.distance(&b));
        assert!(
            same * 3.0 < different,
            "noise moved the descriptor by {same}, another scene by {different}"
        );
        for (x, y) in [(&a, &a_noisy), (&a, &b)] {
            let d = x.distance(y);
            assert!((x.similarity(y) - (1.0 - d * d / 4.0)).abs() < 1e-9);
        }
        assert!(a.similarity(&a_noisy) > a.similarity(&b));
    }

    /// Guards StaticMapping's variant: 64 + 32 × 16 values with its default rings of 0.1 m
    /// out to 100 m, a correlation of 1 with itself, lower with another scene.
    #[test]
    fn m2dp_absolute_rings_and_correlation() {
        let cfg = M2dpConfig::static_mapping();
        assert_eq!(cfg.ring_count(), Some(32));
        let a = descriptor(&cloud(&scene_a(), 5), &cfg).expect("a descriptor");
        assert_eq!(a.values.len(), 64 + 32 * 16);
        assert_eq!(cfg.descriptor_len(), Some(a.values.len()));
        assert!((a.correlation(&a) - 1.0).abs() < 1e-12);
        let b = descriptor(&cloud(&scene_b(), 5), &cfg).expect("a descriptor");
        let c = a.correlation(&b);
        assert!(
            (0.0..0.99).contains(&c),
            "correlation with another scene {c}"
        );
        // l = ⌈√(max_distance / r)⌉.
        let other = M2dpConfig {
            radii: Rings::Absolute {
                ring_m: 0.05,
                max_distance_m: 20.5,
            },
            ..M2dpConfig::default()
        };
        assert_eq!(other.ring_count(), Some(21));
        let d = descriptor(&cloud(&scene_a(), 5), &other).expect("a descriptor");
        assert_eq!(d.values.len(), 64 + 21 * 16);
    }

    /// Guards the refusals: too few points, a line, an invalid configuration.
    #[test]
    fn m2dp_refuses_degenerate_input() {
        let cfg = M2dpConfig::default();
        let few: Vec<Vector3<f64>> = (0..9)
            .map(|i| Vector3::new(i as f64, (i * i) as f64, 0.0))
            .collect();
        assert!(descriptor(&few, &cfg).is_none());
        let line: Vec<Vector3<f64>> = (0..100)
            .map(|i| Vector3::new(1.0, 2.0, 3.0) * i as f64)
            .collect();
        assert!(descriptor(&line, &cfg).is_none());
        let zero_rings = M2dpConfig {
            radii: Rings::Absolute {
                ring_m: 0.0,
                max_distance_m: 10.0,
            },
            ..cfg
        };
        assert!(descriptor(&cloud(&scene_a(), 7), &zero_rings).is_none());
    }
}
