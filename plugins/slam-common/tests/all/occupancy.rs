//! The occupancy grid from simulated planar scans (the simulator's front 2D lidar: 720
//! samples over −2.18…2.36 rad, `+inf` for no return): what is occupied, free and unknown,
//! in the map_server orientation, and how the log-odds change with repeated scans.

use nalgebra::{Isometry2, Vector2};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};
use slam_common::maps::occupancy::{Grid, OccupancyGridBuilder, OccupancyGridConfig};
use slam_common::registration::scan2d::{no_return_directions, points_from_ranges};

const ANGLE_MIN: f64 = -2.18;
const ANGLE_MAX: f64 = 2.36;
const SAMPLES: usize = 720;
const RANGE_MIN: f64 = 0.1;
const RANGE_MAX: f64 = 30.0;

fn increment() -> f64 {
    (ANGLE_MAX - ANGLE_MIN) / (SAMPLES - 1) as f64
}

/// Circles `(centre, radius)` and horizontal walls `y = wall` for |x| < 50.
struct Scene {
    posts: Vec<(Vector2<f64>, f64)>,
    walls: Vec<f64>,
}

impl Scene {
    fn cast(&self, o: &Vector2<f64>, d: &Vector2<f64>) -> Option<f64> {
        let circles = self.posts.iter().filter_map(|(c, r)| {
            let m = o - c;
            let b = m.dot(d);
            let disc = b * b - (m.norm_squared() - r * r);
            (disc >= 0.0).then(|| -b - disc.sqrt())
        });
        let walls = self.walls.iter().filter_map(|y| {
            let t = (y - o.y) / d.y;
            (t.is_finite() && (o.x + t * d.x).abs() < 50.0).then_some(t)
        });
        circles
            .chain(walls)
            .filter(|t| *t > 1e-6)
            .min_by(f64::total_cmp)
    }

    /// A ROS-style scan from `world_from_sensor` with range noise `sigma`.
    fn scan(
        &self,
        world_from_sensor: &Isometry2<f64>,
        sigma: f64,
        rng: &mut ChaCha8Rng,
    ) -> Vec<f32> {
        let noise = Normal::new(0.0, sigma).expect("sigma");
        let o = world_from_sensor.translation.vector;
        (0..SAMPLES)
            .map(|i| {
                let a = ANGLE_MIN + i as f64 * increment();
                let d = world_from_sensor.rotation * Vector2::new(a.cos(), a.sin());
                match self.cast(&o, &d) {
                    Some(t) if (RANGE_MIN..=RANGE_MAX).contains(&t) => {
                        (t + noise.sample(rng)) as f32
                    }
                    _ => f32::INFINITY,
                }
            })
            .collect()
    }
}

fn insert(b: &mut OccupancyGridBuilder, pose: &Isometry2<f64>, ranges: &[f32]) {
    let points = points_from_ranges(ANGLE_MIN, increment(), ranges, RANGE_MIN, RANGE_MAX);
    let free = no_return_directions(ANGLE_MIN, increment(), ranges, RANGE_MAX);
    b.insert_scan(pose, &points, &free);
}

/// Three posts, the first straight to the left (+y), their near faces mid-cell.
fn posts() -> Scene {
    Scene {
        posts: vec![
            (Vector2::new(0.025, 2.025), 0.05),
            (Vector2::new(3.025, 0.025), 0.05),
            (Vector2::new(2.025, -1.975), 0.05),
        ],
        walls: Vec::new(),
    }
}

#[test]
fn posts_occupied_rays_free_shadows_unknown() {
    let mut rng = ChaCha8Rng::seed_from_u64(3);
    let scene = posts();
    let mut b = OccupancyGridBuilder::new(OccupancyGridConfig::default()).expect("valid");
    insert(
        &mut b,
        &Isometry2::identity(),
        &scene.scan(&Isometry2::identity(), 0.01, &mut rng),
    );
    let grid = b.build();
    assert_eq!(grid.resolution_m, 0.05);
    assert_eq!(grid.cells.len(), (grid.width * grid.height) as usize);
    let at = |x: f64, y: f64| grid.value_at(&Vector2::new(x, y));
    // Near faces of the posts (the third's, at −44°, is at (1.989, −1.940)).
    for (x, y) in [(0.025, 1.975), (2.975, 0.025), (1.989, -1.940)] {
        assert_eq!(at(x, y), Grid::OCCUPIED, "post face at ({x}, {y})");
    }
    // Between the sensor and the posts.
    for (x, y) in [
        (0.025, 0.5),
        (0.025, 1.5),
        (1.5, 0.025),
        (2.5, 0.025),
        (1.0, -1.0),
    ] {
        assert_eq!(at(x, y), Grid::FREE, "ray at ({x}, {y})");
    }
    // Behind the posts, in directions with no return, and behind the sensor (outside its
    // field of view): never observed.
    for (x, y) in [
        (0.025, 2.3),
        (3.4, 0.025),
        (2.3, -2.3),
        (1.0, 1.0),
        (-2.0, 0.0),
    ] {
        assert_eq!(at(x, y), Grid::UNKNOWN, "unobserved ({x}, {y})");
    }
    let occupied = grid.cells.iter().filter(|c| **c == Grid::OCCUPIED).count();
    let free = grid.cells.iter().filter(|c| **c == Grid::FREE).count();
    eprintln!(
        "{} x {} cells from {:?}: {occupied} occupied, {free} free",
        grid.width, grid.height, grid.origin
    );
    assert!((3..=15).contains(&occupied), "{occupied} occupied");
}

/// map_server: cell (0, 0) at the origin corner, index `row · width + column`, rows going
/// up in y; a post at +y is in a higher row than the sensor.
#[test]
fn map_server_orientation() {
    let mut rng = ChaCha8Rng::seed_from_u64(4);
    let scene = posts();
    let mut b = OccupancyGridBuilder::new(OccupancyGridConfig::default()).expect("valid");
    insert(
        &mut b,
        &Isometry2::identity(),
        &scene.scan(&Isometry2::identity(), 0.0, &mut rng),
    );
    let grid = b.build();
    let index = |x: f64, y: f64| {
        let col = ((x - grid.origin[0]) / grid.resolution_m).floor() as usize;
        let row = ((y - grid.origin[1]) / grid.resolution_m).floor() as usize;
        (row, col, row * grid.width as usize + col)
    };
    let (sensor_row, sensor_col, sensor) = index(0.01, 0.01);
    let (post_row, post_col, post) = index(0.025, 1.975);
    assert_eq!(grid.cells[sensor], Grid::FREE);
    assert_eq!(grid.cells[post], Grid::OCCUPIED);
    assert_eq!(post_col, sensor_col);
    assert_eq!(post_row, sensor_row + 39, "1.975 m up is 39 rows up");
    let (ahead_row, ahead_col, ahead) = index(2.975, 0.025);
    assert_eq!(grid.cells[ahead], Grid::OCCUPIED);
    assert_eq!((ahead_row, ahead_col), (sensor_row, sensor_col + 59));
    assert_eq!(grid.origin[2], 0.0);
    // The origin is on the cell lattice and the grid is cropped to what was observed: the
    // bottom row and left column each hold an observed cell.
    let w = grid.width as usize;
    assert!(grid.cells[..w].iter().any(|c| *c != Grid::UNKNOWN));
    assert!(grid.cells.iter().step_by(w).any(|c| *c != Grid::UNKNOWN));
}

#[test]
fn no_return_rays_clear_only_when_asked() {
    let mut rng = ChaCha8Rng::seed_from_u64(5);
    let scene = posts();
    let ranges = scene.scan(&Isometry2::identity(), 0.01, &mut rng);
    let config = OccupancyGridConfig {
        no_return_range_m: 5.0,
        ..OccupancyGridConfig::default()
    };
    let mut b = OccupancyGridBuilder::new(config).expect("valid");
    insert(&mut b, &Isometry2::identity(), &ranges);
    let grid = b.build();
    let at = |x: f64, y: f64| grid.value_at(&Vector2::new(x, y));
    assert_eq!(at(1.0, 1.0), Grid::FREE, "no return within 5 m");
    assert_eq!(at(4.0, 2.0), Grid::FREE);
    assert_eq!(at(5.0, 5.0), Grid::UNKNOWN, "beyond 5 m");
    assert_eq!(at(0.025, 1.975), Grid::OCCUPIED, "the post stays");
    assert_eq!(at(0.025, 2.3), Grid::UNKNOWN, "its shadow too");

    // max_range_m cuts returns: the post at 3 m becomes free space ending at 2.5 m.
    let config = OccupancyGridConfig {
        max_range_m: 2.5,
        ..OccupancyGridConfig::default()
    };
    let mut b = OccupancyGridBuilder::new(config).expect("valid");
    insert(&mut b, &Isometry2::identity(), &ranges);
    let grid = b.build();
    let at = |x: f64, y: f64| grid.value_at(&Vector2::new(x, y));
    assert_eq!(at(0.025, 1.975), Grid::OCCUPIED);
    assert_eq!(at(2.0, 0.025), Grid::FREE);
    assert_eq!(at(2.975, 0.025), Grid::UNKNOWN);
}

/// A post seen 100 times saturates at the clamping maximum (logit 0.971 = 3.51); once it is
/// gone, each scan passing through its cell subtracts logit 0.4 = −0.405 once, so it
/// takes nine scans, not one, to be free.
#[test]
fn clamping_lets_a_removed_post_clear() {
    let mut rng = ChaCha8Rng::seed_from_u64(6);
    let with_post = Scene {
        posts: vec![(Vector2::new(0.025, 2.025), 0.05)],
        walls: vec![4.025],
    };
    let without = Scene {
        posts: Vec::new(),
        walls: vec![4.025],
    };
    let pose = Isometry2::identity();
    let mut b = OccupancyGridBuilder::new(OccupancyGridConfig::default()).expect("valid");
    let face = Vector2::new(0.025, 1.975);
    for _ in 0..100 {
        insert(&mut b, &pose, &with_post.scan(&pose, 0.0, &mut rng));
    }
    let p = b.probability(&face).expect("observed");
    assert!((p - 0.971).abs() < 1e-4, "{p}");
    for k in 1..=9 {
        insert(&mut b, &pose, &without.scan(&pose, 0.0, &mut rng));
        let value = b.build().value_at(&face);
        let expected = if k < 9 { Grid::OCCUPIED } else { Grid::FREE };
        assert_eq!(value, expected, "after {k} scans without the post");
    }
    // The wall behind is occupied, the space in front of it free.
    let grid = b.build();
    assert_eq!(grid.value_at(&Vector2::new(0.025, 4.025)), Grid::OCCUPIED);
    assert_eq!(grid.value_at(&Vector2::new(0.025, 3.0)), Grid::FREE);
    // Free cells saturate at the clamping minimum.
    let p = b.probability(&Vector2::new(0.025, 1.0)).expect("observed");
    assert!((p - 0.1192).abs() < 1e-4, "{p}");
}

/// Driving down a vine row: the trunks of both rows near the path are occupied, the
/// headland between them free; the same inputs give the same grid.
#[test]
fn a_vine_row_driven_through() {
    let row = |y: f64| (-10..=10).map(move |k| (Vector2::new(k as f64, y), 0.05));
    let scene = Scene {
        posts: row(-1.5).chain(row(1.5)).collect(),
        walls: Vec::new(),
    };
    let run = || {
        let mut rng = ChaCha8Rng::seed_from_u64(8);
        let mut b = OccupancyGridBuilder::new(OccupancyGridConfig::default()).expect("valid");
        for i in 0..40 {
            let pose = Isometry2::new(Vector2::new(-4.0 + 0.2 * i as f64, 0.0), 0.0);
            insert(&mut b, &pose, &scene.scan(&pose, 0.01, &mut rng));
        }
        b.build()
    };
    let grid = run();
    assert_eq!(grid, run(), "deterministic");
    for k in -3..=4 {
        for y in [-1.5, 1.5] {
            let centre = Vector2::new(k as f64, y);
            // Some cell of the trunk (within its radius plus one cell) is occupied.
            let hit = (-2..=2).any(|i| {
                (-2..=2).any(|j| {
                    let p = centre + Vector2::new(i as f64, j as f64) * 0.025;
                    grid.value_at(&p) == Grid::OCCUPIED
                })
            });
            assert!(hit, "trunk at {centre:?}");
        }
        // The path, and half-way from it to the trunks abeam.
        for y in [0.0, -0.75, 0.75] {
            let p = Vector2::new(k as f64 + 0.025, y);
            assert_eq!(grid.value_at(&p), Grid::FREE, "{p:?}");
        }
    }
}
