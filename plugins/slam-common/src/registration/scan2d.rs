//! Planar laser scans and their 3-DoF registration, for odometry refined by scan matching
//! (RTAB-Map's `Reg/Strategy=1` on a 2D laser).
//!
//! - [`points_from_ranges`], [`no_return_directions`]: a ROS `sensor_msgs/LaserScan` as
//!   points and as the directions of its rays that met nothing (REP 117: `+inf`);
//! - [`downsample`]: grid thinning of a point set (RTAB-Map's `Icp/VoxelSize`);
//! - [`KdTree2`]: the static k-d tree of [`crate::registration::kdtree`] over 2-d points, for nearest
//!   neighbours;
//! - [`Icp2dTarget`], [`icp2d`]: point-to-line ICP.
//!
//! # ICP
//!
//! The metric is the point-to-line distance of Censi ("An ICP variant using a point-to-line
//! metric", ICRA 2008), which is Chen and Medioni's point-to-plane metric ("Object modelling
//! by registration of multiple range images", 1992) in the plane: every target point
//! carries the normal of the line fitted (by principal components) to its nearest
//! neighbours, and a source point matched to it contributes its distance to that line.
//! Target points whose neighbourhood is not a line — a trunk or post a couple of samples
//! wide, a tuft of foliage — are matched point-to-point instead, so that they still fix the
//! translation along a vine row, which the lines of the row cannot. A point with no
//! neighbour within the normal radius takes the line of its nearest neighbours at any
//! distance when they are collinear, so that a wall or hedge sampled sparsely (far away, at
//! a grazing angle) stays a line and does not pretend to fix the position along it (see
//! [`Icp2dConfig::normal_neighbours`]).
//!
//! Each iteration matches every source point to its nearest target point within a gate,
//! weights the residuals with Huber's kernel, and takes one Gauss–Newton step. The gate
//! schedule is coarse to fine: it starts at [`Icp2dConfig::coarse_correspondence_m`] and
//! is halved whenever a step is below the convergence thresholds or after
//! [`STAGE_ITERATIONS`] steps at one gate, until it reaches
//! [`Icp2dConfig::max_correspondence_m`]; iterations then continue at that gate until a
//! step is below the thresholds (converged) or [`Icp2dConfig::max_iterations`] steps have
//! been taken in all. Inliers, ratio, RMSE and information are those at the fine gate at
//! the final pose.
//!
//! The update is a right perturbation `[δθ, δx, δy]` about the source sensor,
//! `target_from_source ← target_from_source ∘ (Rot(δθ), δt)`, the convention of
//! [`crate::motion::lsq`] and of the backend (rotation first, perturbation in the body frame): a
//! source point `p` moves by `R (δθ p⊥ + δt)` with `p⊥ = (−p_y, p_x)`, so a residual with
//! gradient `g` (in the target frame) has the Jacobian `[p × Rᵀg, (Rᵀg)ᵀ]`.
//!
//! # Degeneracy
//!
//! Following Zhang, Kaess and Singh ("On degeneracy of optimization-based state estimation
//! problems", ICRA 2016), directions of the normal matrix `JᵀJ` whose eigenvalue is below a
//! threshold are not updated, so that the initial guess stands along them (the translation
//! along a corridor, or along a vine row whose posts are hidden by foliage). To make one
//! threshold meaningful for rotation and translation alike, the eigen-analysis is done on
//! `S JᵀJ S / Σw` with `S = diag(1/L, 1, 1)`, `L` the root-mean-square range of the matched
//! source points and `Σw` their summed weights: a translation eigenvalue is then the mean
//! squared component of the matched normals along that direction (1 for point-to-point
//! matches), and a rotation eigenvalue the same for the motion of the points under a
//! rotation of one radian per `L` metres.

use nalgebra::{Isometry2, Matrix2, Matrix3, SymmetricEigen, Vector2, Vector3};
use serde::Deserialize;

pub use crate::registration::kdtree::KdTree2;
use crate::registration::kdtree::Neighbour;

/// Points of a ROS `LaserScan` in the sensor frame: sample `i` is at angle `angle_min_rad +
/// i · angle_increment_rad` from the x axis, counter-clockwise. Returns that are not finite
/// (`±inf`, NaN: REP 117) or outside `[range_min_m, range_max_m]` are skipped.
pub fn points_from_ranges(
    angle_min_rad: f64,
    angle_increment_rad: f64,
    ranges_m: &[f32],
    range_min_m: f64,
    range_max_m: f64,
) -> Vec<Vector2<f64>> {
    ranges_m
        .iter()
        .enumerate()
        .filter_map(|(i, &r)| {
            let r = f64::from(r);
            (r.is_finite() && r >= range_min_m && r <= range_max_m).then(|| {
                let a = angle_min_rad + i as f64 * angle_increment_rad;
                Vector2::new(r * a.cos(), r * a.sin())
            })
        })
        .collect()
}

/// Unit directions (sensor frame) of the samples of a `LaserScan` that met nothing within
/// range: `+inf` (REP 117) or a finite value above `range_max_m` (drivers that report
/// `range_max + 1`). NaN (an erroneous sample) and `-inf` (too close) are not included.
/// For [`crate::maps::occupancy::OccupancyGridBuilder::insert_scan`].
pub fn no_return_directions(
    angle_min_rad: f64,
    angle_increment_rad: f64,
    ranges_m: &[f32],
    range_max_m: f64,
) -> Vec<Vector2<f64>> {
    ranges_m
        .iter()
        .enumerate()
        .filter(|(_, r)| f64::from(**r) > range_max_m)
        .map(|(i, _)| {
            let a = angle_min_rad + i as f64 * angle_increment_rad;
            Vector2::new(a.cos(), a.sin())
        })
        .collect()
}

/// Grid thinning: every occupied square cell of edge `leaf_m` is replaced by the centroid of
/// its points (the 2D form of [`crate::registration::voxel::downsample`]). Non-finite points are dropped;
/// a non-positive (or non-finite) leaf returns the others unchanged. The output is ordered
/// by cell, so that it depends on the geometry, not on the order of the input.
pub fn downsample(points: &[Vector2<f64>], leaf_m: f64) -> Vec<Vector2<f64>> {
    let finite = points.iter().filter(|p| p.x.is_finite() && p.y.is_finite());
    if leaf_m <= 0.0 || !leaf_m.is_finite() {
        return finite.copied().collect();
    }
    let inv = 1.0 / leaf_m;
    let mut keyed: Vec<([i64; 2], Vector2<f64>)> = finite
        .map(|p| ([(p.x * inv).floor() as i64, (p.y * inv).floor() as i64], *p))
        .collect();
    // Stable, so the points of one cell are summed in input order.
    keyed.sort_by_key(|k| k.0);
    keyed
        .chunk_by(|a, b| a.0 == b.0)
        .map(|cell| cell.iter().map(|k| k.1).sum::<Vector2<f64>>() / cell.len() as f64)
        .collect()
}

/// Steps taken at one coarse gate before it is halved anyway (see the module docs).
pub const STAGE_ITERATIONS: usize = 3;

/// Settings of [`icp2d`] and [`Icp2dTarget::new`]. Defaults follow RTAB-Map where it has
/// the parameter (named in brackets).
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct Icp2dConfig {
    /// Edge of the thinning grid applied to source and target, m; 0 keeps every point
    /// (`Icp/VoxelSize`, 0.05).
    pub voxel_size_m: f64,
    /// Gauss–Newton steps in all, coarse stages included (`Icp/Iterations`, 30).
    pub max_iterations: usize,
    /// The final gate: correspondences farther apart are ignored, m
    /// (`Icp/MaxCorrespondenceDistance`, 0.1).
    pub max_correspondence_m: f64,
    /// The first gate, halved down to `max_correspondence_m`, m (0.5). Set it equal to
    /// `max_correspondence_m` for a single stage.
    pub coarse_correspondence_m: f64,
    /// A step whose translation and rotation are both below these has converged
    /// (`Icp/Epsilon`): m and rad.
    pub epsilon_translation_m: f64,
    pub epsilon_rotation_rad: f64,
    /// Neighbours (the point itself included) a target normal is fitted to
    /// (`Icp/PointToPlaneK`, 5) and how far they may be, m (0.3). A target point with
    /// at least three points within the radius is on a line if they are flat enough
    /// (`max_line_flatness`) and matched point-to-point otherwise; with two (a trunk or
    /// post a couple of samples wide) it is matched point-to-point; alone within the
    /// radius, its nearest neighbours at any distance (RTAB-Map's `Icp/PointToPlaneRadius`
    /// 0) decide: on their line if they are flat enough (a surface sampled sparsely, far
    /// away or at a grazing angle), point-to-point otherwise.
    pub normal_neighbours: usize,
    pub normal_radius_m: f64,
    /// A neighbourhood is a line when its smaller principal variance is at most this
    /// fraction of the larger (0.1, i.e. a thickness of about a third of its length);
    /// other target points are matched point-to-point.
    pub max_line_flatness: f64,
    /// Huber kernel width, m: residuals beyond it are down-weighted (0.03, three times the
    /// range noise of a typical 2D lidar); 0 disables the kernel.
    pub robust_kernel_m: f64,
    /// Fewer matched source points than this, in any iteration or at the end, and
    /// [`icp2d`] returns None (20).
    pub min_correspondences: usize,
    /// A smaller ratio of inliers to (thinned) source points at the end and [`icp2d`]
    /// returns None (`Icp/CorrespondenceRatio`, 0.2). 0 accepts every ratio.
    pub min_correspondence_ratio: f64,
    /// Directions whose normalised eigenvalue (module docs) is below this are degenerate
    /// and not updated (0.05: fewer than one matched normal in twenty along it).
    pub degeneracy_min_eigenvalue: f64,
    /// Floor of the residual standard deviation used for the information matrix, m (0.01).
    pub min_sigma_m: f64,
}

impl Default for Icp2dConfig {
    fn default() -> Self {
        Self {
            voxel_size_m: 0.05,
            max_iterations: 30,
            max_correspondence_m: 0.1,
            coarse_correspondence_m: 0.5,
            epsilon_translation_m: 1e-4,
            epsilon_rotation_rad: 1e-4,
            normal_neighbours: 5,
            normal_radius_m: 0.3,
            max_line_flatness: 0.1,
            robust_kernel_m: 0.03,
            min_correspondences: 20,
            min_correspondence_ratio: 0.2,
            degeneracy_min_eigenvalue: 0.05,
            min_sigma_m: 0.01,
        }
    }
}

/// What a target point is matched as.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum TargetFeature {
    /// On a line with this unit normal: point-to-line residual.
    Line { normal: Vector2<f64> },
    /// Isolated or not line-like: point-to-point residual.
    Point,
}

/// A target scan ready for [`icp2d`]: thinned, indexed, each point with its feature. Build
/// it once and register several sources against it.
#[derive(Debug, Clone, Default)]
pub struct Icp2dTarget {
    tree: KdTree2,
    features: Vec<TargetFeature>,
}

impl Icp2dTarget {
    /// Thins `points` by `config.voxel_size_m` and fits a line to the
    /// `config.normal_neighbours` nearest neighbours of every point.
    pub fn new(points: &[Vector2<f64>], config: &Icp2dConfig) -> Self {
        let tree = KdTree2::new(downsample(points, config.voxel_size_m));
        let radius_sq = config.normal_radius_m * config.normal_radius_m;
        let mut found = Vec::new();
        let features = tree
            .points()
            .iter()
            .map(|p| {
                tree.nearest(p, config.normal_neighbours, radius_sq, &mut found);
                if found.len() == 1 {
                    // Alone within the radius: a surface sampled sparsely (far away, or at a
                    // grazing angle) or a small isolated object. Its nearest neighbours at
                    // any distance tell which: collinear, it lies on their line.
                    tree.nearest(p, config.normal_neighbours, f64::INFINITY, &mut found);
                } else if found.len() < 3 {
                    // A small object sampled twice: a trunk, a post.
                    return TargetFeature::Point;
                }
                line_normal(&tree, &found, config.max_line_flatness)
                    .map_or(TargetFeature::Point, |normal| TargetFeature::Line {
                        normal,
                    })
            })
            .collect();
        Self { tree, features }
    }

    pub fn len(&self) -> usize {
        self.tree.len()
    }

    pub fn is_empty(&self) -> bool {
        self.tree.is_empty()
    }

    /// The thinned target points (in the tree's order).
    pub fn points(&self) -> &[Vector2<f64>] {
        self.tree.points()
    }

    /// The feature of [`Icp2dTarget::points`]`[i]`.
    pub fn feature(&self, i: usize) -> TargetFeature {
        self.features[i]
    }
}

/// The unit normal of the principal line through the neighbours, if there are at least three
/// and their smaller principal variance is at most `max_flatness` times the larger.
fn line_normal(tree: &KdTree2, found: &[Neighbour], max_flatness: f64) -> Option<Vector2<f64>> {
    if found.len() < 3 {
        return None;
    }
    let n = found.len() as f64;
    let mean = found
        .iter()
        .map(|f| tree.point(f.index))
        .sum::<Vector2<f64>>()
        / n;
    let cov = found
        .iter()
        .map(|f| {
            let d = tree.point(f.index) - mean;
            d * d.transpose()
        })
        .sum::<Matrix2<f64>>()
        / n;
    let eig = SymmetricEigen::new(cov);
    let (small, large) = if eig.eigenvalues[0] <= eig.eigenvalues[1] {
        (0, 1)
    } else {
        (1, 0)
    };
    let (l_small, l_large) = (eig.eigenvalues[small].max(0.0), eig.eigenvalues[large]);
    (l_large > 0.0 && l_small <= max_flatness * l_large)
        .then(|| eig.eigenvectors.column(small).normalize())
}

/// The outcome of [`icp2d`].
#[derive(Debug, Clone, PartialEq)]
pub struct Icp2dResult {
    pub target_from_source: Isometry2<f64>,
    /// Thinned source points matched within `max_correspondence_m` at the result.
    pub inliers: usize,
    /// `inliers` over the thinned source points.
    pub correspondence_ratio: f64,
    /// Root-mean-square residual of the inliers (point-to-line or point-to-point), m.
    pub rmse_m: f64,
    /// `JᵀJ / σ²` at the result, for a factor on `target_from_source`: tangent order
    /// `[θ, x, y]`, right perturbation (about the source sensor); `J` includes the Huber
    /// weights and `σ = max(rmse_m, min_sigma_m)`.
    pub information: Matrix3<f64>,
    /// Gauss–Newton steps taken.
    pub iterations: usize,
    /// Whether a step at the final gate fell below the convergence thresholds.
    pub converged: bool,
    /// Eigenvalues of the normalised normal matrix at the result, ascending (module docs).
    pub eigenvalues: Vector3<f64>,
    /// Unit directions in the tangent `[θ, x, y]` whose normalised eigenvalue was below
    /// `degeneracy_min_eigenvalue` at the result; the initial guess was kept along them.
    /// Empty when the scan constrains all three.
    pub degenerate_directions: Vec<Vector3<f64>>,
}

impl Icp2dResult {
    pub fn is_degenerate(&self) -> bool {
        !self.degenerate_directions.is_empty()
    }
}

/// Normal equations `H δ = b` over `[δθ, δx, δy]`, from weighted scalar residuals.
#[derive(Debug, Clone, Copy)]
struct Normal3 {
    h: Matrix3<f64>,
    b: Vector3<f64>,
    /// Matched source points, their summed weights, `Σ w |p|²` and `Σ |residual|²`.
    count: usize,
    weight: f64,
    lever_sq: f64,
    sum_sq: f64,
}

impl Default for Normal3 {
    fn default() -> Self {
        Self {
            h: Matrix3::zeros(),
            b: Vector3::zeros(),
            count: 0,
            weight: 0.0,
            lever_sq: 0.0,
            sum_sq: 0.0,
        }
    }
}

/// The normalised eigen-decomposition: eigenvalues ascending, and the matching columns.
struct Spectrum {
    scale: Vector3<f64>,
    values: Vector3<f64>,
    vectors: Matrix3<f64>,
}

impl Normal3 {
    /// Residual `r` of source point `p` whose gradient rotated into the source frame is `g`.
    fn add(&mut self, p: &Vector2<f64>, g: &Vector2<f64>, r: f64, w: f64) {
        let j = Vector3::new(p.x * g.y - p.y * g.x, g.x, g.y);
        self.h += w * j * j.transpose();
        self.b -= w * r * j;
    }

    fn spectrum(&self) -> Option<Spectrum> {
        if self.weight <= 0.0 {
            return None;
        }
        let lever = (self.lever_sq / self.weight).sqrt().max(0.1);
        let scale = Vector3::new(1.0 / lever, 1.0, 1.0);
        let hs = self.h.component_mul(&(scale * scale.transpose())) / self.weight;
        let eig = SymmetricEigen::new(hs);
        let mut order = [0, 1, 2];
        order.sort_by(|&a, &b| eig.eigenvalues[a].total_cmp(&eig.eigenvalues[b]));
        let values = Vector3::from_fn(|i, _| eig.eigenvalues[order[i]]);
        let vectors = Matrix3::from_fn(|r, c| eig.eigenvectors[(r, order[c])]);
        Some(Spectrum {
            scale,
            values,
            vectors,
        })
    }

    /// The update `[δθ, δx, δy]` leaving out the degenerate directions.
    fn solve(&self, min_eigenvalue: f64) -> Option<Vector3<f64>> {
        let s = self.spectrum()?;
        let bs = self.b.component_mul(&s.scale) / self.weight;
        let mut delta = Vector3::zeros();
        for i in 0..3 {
            let lambda = s.values[i];
            if lambda < min_eigenvalue.max(1e-12) {
                continue;
            }
            let v = s.vectors.column(i);
            delta += v * (v.dot(&bs) / lambda);
        }
        let delta = delta.component_mul(&s.scale);
        delta.iter().all(|x| x.is_finite()).then_some(delta)
    }
}

/// Huber's weight for a residual of magnitude `r` (1 when the kernel is off).
fn huber(r: f64, width: f64) -> f64 {
    if width > 0.0 && r > width {
        width / r
    } else {
        1.0
    }
}

/// Matches every source point within `gate` and accumulates its residuals at `pose`.
fn accumulate(
    source: &[Vector2<f64>],
    target: &Icp2dTarget,
    pose: &Isometry2<f64>,
    gate: f64,
    config: &Icp2dConfig,
) -> Normal3 {
    let gate_sq = gate * gate;
    let inv_rot = pose.rotation.inverse();
    let mut ne = Normal3::default();
    for p in source {
        let q = pose * nalgebra::Point2::from(*p);
        let Some(nb) = target.tree.nearest_one(&q.coords, gate_sq) else {
            continue;
        };
        let e = q.coords - target.tree.point(nb.index);
        let (magnitude, w) = match target.features[nb.index] {
            TargetFeature::Line { normal } => {
                let r = normal.dot(&e);
                let w = huber(r.abs(), config.robust_kernel_m);
                ne.add(p, &(inv_rot * normal), r, w);
                (r.abs(), w)
            }
            TargetFeature::Point => {
                let d = e.norm();
                let w = huber(d, config.robust_kernel_m);
                ne.add(p, &(inv_rot * Vector2::x()), e.x, w);
                ne.add(p, &(inv_rot * Vector2::y()), e.y, w);
                (d, w)
            }
        };
        ne.count += 1;
        ne.weight += w;
        ne.lever_sq += w * p.norm_squared();
        ne.sum_sq += magnitude * magnitude;
    }
    ne
}

/// Applies `[δθ, δx, δy]` on the right of `pose`.
fn apply(delta: &Vector3<f64>, pose: &Isometry2<f64>) -> Isometry2<f64> {
    let mut out = pose * Isometry2::new(Vector2::new(delta[1], delta[2]), delta[0]);
    out.rotation.renormalize();
    out
}

/// Registers `source` (sensor-frame points of the newer scan) to `target`, starting from
/// `initial_target_from_source` (e.g. wheel odometry). The source is thinned as the target
/// was. None when fewer than `config.min_correspondences` source points are matched in any
/// iteration or at the end, or when the final correspondence ratio is below
/// `config.min_correspondence_ratio`. See the module docs for the schedule.
pub fn icp2d(
    source: &[Vector2<f64>],
    target: &Icp2dTarget,
    initial_target_from_source: Isometry2<f64>,
    config: &Icp2dConfig,
) -> Option<Icp2dResult> {
    let source = downsample(source, config.voxel_size_m);
    let min_count = config.min_correspondences.max(3);
    if source.len() < min_count || target.is_empty() {
        return None;
    }
    let fine = config.max_correspondence_m;
    let mut gate = config.coarse_correspondence_m.max(fine);
    let mut pose = initial_target_from_source;
    let (mut iterations, mut at_gate, mut converged) = (0, 0, false);
    while iterations < config.max_iterations {
        let ne = accumulate(&source, target, &pose, gate, config);
        if ne.count < min_count {
            return None;
        }
        let delta = ne.solve(config.degeneracy_min_eigenvalue)?;
        pose = apply(&delta, &pose);
        iterations += 1;
        at_gate += 1;
        let small = delta[0].abs() < config.epsilon_rotation_rad
            && Vector2::new(delta[1], delta[2]).norm() < config.epsilon_translation_m;
        if gate > fine {
            if small || at_gate >= STAGE_ITERATIONS {
                gate = (gate * 0.5).max(fine);
                at_gate = 0;
            }
        } else if small {
            converged = true;
            break;
        }
    }
    let ne = accumulate(&source, target, &pose, fine, config);
    let ratio = ne.count as f64 / source.len() as f64;
    if ne.count < min_count || ratio < config.min_correspondence_ratio {
        return None;
    }
    let spectrum = ne.spectrum()?;
    let degenerate_directions = (0..3)
        .filter(|&i| spectrum.values[i] < config.degeneracy_min_eigenvalue)
        .map(|i| {
            spectrum
                .vectors
                .column(i)
                .component_mul(&spectrum.scale)
                .normalize()
        })
        .collect();
    let rmse_m = (ne.sum_sq / ne.count as f64).sqrt();
    let sigma = rmse_m.max(config.min_sigma_m);
    Some(Icp2dResult {
        target_from_source: pose,
        inliers: ne.count,
        correspondence_ratio: ratio,
        rmse_m,
        information: ne.h / (sigma * sigma),
        iterations,
        converged,
        eigenvalues: spectrum.values,
        degenerate_directions,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn one_centroid_per_cell_in_cell_order() {
        let points = vec![
            Vector2::new(0.31, 0.1),
            Vector2::new(0.1, 0.1),
            Vector2::new(0.3, 0.1),
            Vector2::new(-0.1, 0.1),
            Vector2::new(f64::NAN, 0.0),
        ];
        let out = downsample(&points, 0.25);
        assert_eq!(
            out,
            vec![
                Vector2::new(-0.1, 0.1),
                Vector2::new(0.1, 0.1),
                Vector2::new((0.31 + 0.3) / 2.0, 0.1)
            ]
        );
        assert_eq!(downsample(&points, 0.0), points[..4].to_vec());
    }

    #[test]
    fn scan_layout_is_ros() {
        let ranges = [
            1.0,
            f32::INFINITY,
            f32::NAN,
            0.05,
            2.0,
            f32::NEG_INFINITY,
            40.0,
        ];
        let inc = std::f64::consts::FRAC_PI_2;
        let points = points_from_ranges(0.0, inc, &ranges, 0.1, 30.0);
        assert_eq!(points.len(), 2, "{points:?}");
        assert!((points[0] - Vector2::new(1.0, 0.0)).norm() < 1e-12);
        // Sample 4 is at 2π: straight ahead again.
        assert!((points[1] - Vector2::new(2.0, 0.0)).norm() < 1e-9);
        let free = no_return_directions(0.0, inc, &ranges, 30.0);
        assert_eq!(free.len(), 2, "+inf and the return beyond range: {free:?}");
        assert!((free[0] - Vector2::new(0.0, 1.0)).norm() < 1e-12);
    }

    /// A square room: lines on four sides, so the point-to-line step recovers a small
    /// offset exactly from noise-free points.
    #[test]
    fn aligns_a_square_room() {
        let mut room = Vec::new();
        for i in 0..=100 {
            let u = -2.0 + i as f64 * 0.04;
            room.extend([
                Vector2::new(u, -2.0),
                Vector2::new(u, 2.5),
                Vector2::new(-2.0, u),
                Vector2::new(3.0, u),
            ]);
        }
        let truth = Isometry2::new(Vector2::new(0.07, -0.04), 0.03);
        let source: Vec<_> = room
            .iter()
            .map(|p| (truth.inverse() * nalgebra::Point2::from(*p)).coords)
            .collect();
        let config = Icp2dConfig::default();
        let target = Icp2dTarget::new(&room, &config);
        let result = icp2d(&source, &target, Isometry2::identity(), &config).expect("aligned");
        let err = result.target_from_source.inverse() * truth;
        assert!(
            err.translation.vector.norm() < 2e-3 && err.rotation.angle().abs() < 1e-3,
            "{err:?}"
        );
        assert!(!result.is_degenerate(), "{:?}", result.eigenvalues);
    }
}
