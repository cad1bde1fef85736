//! Embree (`raycaster = "embree"`) against our BVH on the default world: full VLP-16 sweeps
//! from poses along S3 and random rays through the whole scene must agree on hit or miss and
//! on the triangle, and on `t` to a few ulps. Embree's triangle test rounds differently from
//! ours, so where a ray passes within rounding of the edge two triangles share, the two can
//! name different triangles (or one can slip through the crack): every such case is counted,
//! checked in f64 to be exactly that, and bounded. Also: Embree's answers and the lidar scans
//! made with it do not depend on the build or the number of threads.
#![cfg(feature = "embree")]

use embree::{Packet, SceneOptions};
use nalgebra::{Point3, Vector3};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use sim::config::{RaycasterKind, SimConfig};
use sim::raycast::{Bvh, EmbreeCaster, Hit, RayCaster};
use sim::sensors::vlp16_directions;
use sim::world::Mesh;
use sim::{SensorSet, Simulation};

/// The bench's lidar range gate.
const T_MIN: f32 = 0.9;
const T_MAX: f32 = 130.0;

/// A ray and what each caster answered.
struct Case {
    o: Point3<f32>,
    d: Vector3<f32>,
    t_min: f32,
    t_max: f32,
    bvh: Option<Hit>,
    embree: Option<Hit>,
}

/// Where the ray meets triangle `i`'s plane, in f64: the ray parameter and how far outside
/// the triangle that point lies (0 inside or on an edge), in metres.
fn probe(mesh: &Mesh, i: u32, o: &Point3<f32>, d: &Vector3<f32>) -> (f64, f64) {
    let [a, b, c] = mesh.corners(i as usize).map(|p| p.cast::<f64>());
    let (o, d) = (o.cast::<f64>(), d.cast::<f64>());
    let n = (b - a).cross(&(c - a));
    let t = n.dot(&(a - o)) / n.dot(&d);
    let p = o + d * t;
    let inside = [(a, b), (b, c), (c, a)]
        .iter()
        .all(|(u, v)| (v - u).cross(&(p - u)).dot(&n) >= 0.0);
    let seg = |u: Point3<f64>, v: Point3<f64>| {
        let s = ((p - u).dot(&(v - u)) / (v - u).norm_squared()).clamp(0.0, 1.0);
        (p - (u + (v - u) * s)).norm()
    };
    let outside = if inside {
        0.0
    } else {
        seg(a, b).min(seg(b, c)).min(seg(c, a))
    };
    (t, outside)
}

/// Rounding scale of a hit at distance `t` from `o`: f32 coordinates there are good to about
/// `|p| * 2^-24`, and both triangle tests lose a few of those.
fn scale(o: &Point3<f32>, t: f32) -> f64 {
    f64::from(o.coords.amax() + t + 1.0) * f64::from(f32::EPSILON)
}

/// Edge slack: a ray within this many rounding scales of a triangle's edge may be called a
/// hit or a miss by either test.
const EDGE_SCALES: f64 = 16.0;

#[derive(Debug, Default)]
struct Tally {
    rays: usize,
    hits: usize,
    /// Same triangle: largest |t_embree - t_bvh| in ulps of t_bvh.
    max_ulps: f32,
    /// Same triangle, bitwise-equal t.
    equal_t: usize,
    /// Same triangle: largest |t_embree - t_bvh| in metres.
    max_dt_m: f32,
    /// Same triangle: largest error of each caster's t against the f64 intersection, in
    /// rounding scales over the cosine of the incidence angle (bvh, embree).
    max_err_scaled: (f64, f64),
    /// Different triangles hit, both within the edge slack at the same t: a shared edge.
    edge_ties: usize,
    /// Different triangles at different t, the nearer one hit within the edge slack of its
    /// border (the other caster slipped through): a crack.
    cracks: usize,
    /// Hit by one, missed by the other, the hit within the edge slack of its border.
    edge_misses: usize,
    /// Everything else: must stay empty.
    unexplained: Vec<String>,
    /// Largest distance outside its triangle of a hit either caster reported, in scales.
    max_outside_scales: f64,
}

impl Tally {
    fn add(&mut self, mesh: &Mesh, c: &Case) {
        self.rays += 1;
        for h in [c.bvh, c.embree].into_iter().flatten() {
            let (_, out) = probe(mesh, h.triangle, &c.o, &c.d);
            self.max_outside_scales = self.max_outside_scales.max(out / scale(&c.o, h.t));
        }
        let near_edge = |h: Hit| {
            let (_, out) = probe(mesh, h.triangle, &c.o, &c.d);
            out <= EDGE_SCALES * scale(&c.o, h.t)
        };
        match (c.bvh, c.embree) {
            (None, None) => {}
            (Some(b), Some(e)) if b.triangle == e.triangle => {
                self.hits += 1;
                let ulps = (e.t - b.t).abs() / (b.t.abs() * f32::EPSILON);
                self.max_ulps = self.max_ulps.max(ulps);
                self.equal_t += usize::from(e.t == b.t);
                self.max_dt_m = self.max_dt_m.max((e.t - b.t).abs());
                let (t64, _) = probe(mesh, b.triangle, &c.o, &c.d);
                let [p, q, r] = mesh.corners(b.triangle as usize).map(|p| p.cast::<f64>());
                let cos = (q - p)
                    .cross(&(r - p))
                    .normalize()
                    .dot(&c.d.cast::<f64>())
                    .abs();
                let unit = scale(&c.o, b.t) / cos;
                let eb = (f64::from(b.t) - t64).abs() / unit;
                let ee = (f64::from(e.t) - t64).abs() / unit;
                self.max_err_scaled.0 = self.max_err_scaled.0.max(eb);
                self.max_err_scaled.1 = self.max_err_scaled.1.max(ee);
            }
            (Some(b), Some(e)) => {
                self.hits += 1;
                let (near, far) = if b.t <= e.t { (b, e) } else { (e, b) };
                let same_t =
                    f64::from((b.t - e.t).abs()) <= EDGE_SCALES * scale(&c.o, b.t.max(e.t));
                if same_t && near_edge(b) && near_edge(e) {
                    self.edge_ties += 1;
                } else if near_edge(near) && far.t > near.t {
                    self.cracks += 1;
                } else {
                    self.unexplained.push(self.describe(mesh, c));
                }
            }
            (Some(h), None) | (None, Some(h)) => {
                if near_edge(h)
                    || h.t <= c.t_min * (1.0 + 4.0 * f32::EPSILON)
                    || h.t >= c.t_max * (1.0 - 4.0 * f32::EPSILON)
                {
                    self.edge_misses += 1;
                } else {
                    self.unexplained.push(self.describe(mesh, c));
                }
            }
        }
    }

    fn describe(&self, mesh: &Mesh, c: &Case) -> String {
        let show = |h: Option<Hit>| {
            h.map_or("miss".to_owned(), |h| {
                let (t, out) = probe(mesh, h.triangle, &c.o, &c.d);
                format!(
                    "tri {} t {} (f64 {t:.9}, {out:.3e} m outside)",
                    h.triangle, h.t
                )
            })
        };
        format!(
            "o {:?} d {:?}: bvh {}, embree {}",
            c.o.coords.as_slice(),
            c.d.as_slice(),
            show(c.bvh),
            show(c.embree)
        )
    }

    fn disagreements(&self) -> usize {
        self.edge_ties + self.cracks + self.edge_misses + self.unexplained.len()
    }
}

fn default_world() -> (SimConfig, Simulation) {
    let cfg = SimConfig::default();
    let sim = Simulation::new(&cfg, "s3", 0).expect("s3 builds");
    (cfg, sim)
}

/// Full VLP-16 sweeps (cast as the lidar does, in fans of a column) from `poses` lidar
/// origins along the route, plus the same rays one at a time through `cast`, which must give
/// exactly the fans' answers.
fn sweeps(
    cfg: &SimConfig,
    sim: &Simulation,
    bvh: &Bvh,
    embree: &EmbreeCaster,
    poses: usize,
) -> Vec<Case> {
    let dirs = vlp16_directions(&cfg.sensors.lidar);
    let mut cases = Vec::new();
    for k in 0..poses {
        let stamp = sim.duration_ns() * (2 * k as i64 + 1) / (2 * poses as i64);
        let pose = sim.trajectory.pose(stamp);
        let o: Point3<f32> =
            Point3::from((pose.translation.vector + Vector3::new(0.0, 0.0, 1.56)).cast());
        let rot = pose.rotation.cast::<f32>();
        let world: Vec<Vector3<f32>> = dirs.iter().map(|d| rot * d).collect();
        let mut b = vec![None; world.len()];
        let mut e = vec![None; world.len()];
        for ((d, b), e) in world.chunks(16).zip(b.chunks_mut(16)).zip(e.chunks_mut(16)) {
            bvh.cast_fan(&o, d, T_MIN, T_MAX, b);
            embree.cast_fan(&o, d, T_MIN, T_MAX, e);
        }
        for (i, d) in world.iter().enumerate() {
            assert_eq!(
                embree.cast(&o, d, T_MIN, T_MAX),
                e[i],
                "Embree's single ray and its packet disagree (pose {k}, ray {i})"
            );
            cases.push(Case {
                o,
                d: *d,
                t_min: T_MIN,
                t_max: T_MAX,
                bvh: b[i],
                embree: e[i],
            });
        }
    }
    cases
}

/// Rays from anywhere in the scene's box (and up to 3 m above it) in uniformly random
/// directions, t in [0, 200 m].
fn random_rays(sim: &Simulation, bvh: &Bvh, embree: &EmbreeCaster, n: usize) -> Vec<Case> {
    let (lo, hi) = sim.world.mesh.bounds().expect("non-empty world");
    let mut rng = ChaCha8Rng::seed_from_u64(17);
    (0..n)
        .map(|_| {
            let (o, d) = crate::random_ray(&mut rng, &lo, &hi);
            Case {
                o,
                d,
                t_min: 0.0,
                t_max: 200.0,
                bvh: bvh.cast(&o, &d, 0.0, 200.0),
                embree: embree.cast(&o, &d, 0.0, 200.0),
            }
        })
        .collect()
}

fn check(name: &str, mesh: &Mesh, cases: &[Case]) -> Tally {
    let mut tally = Tally::default();
    for c in cases {
        tally.add(mesh, c);
    }
    eprintln!("{name}: {tally:#?}");
    assert!(
        tally.unexplained.is_empty(),
        "{name}: {} disagreements that are not edge rounding:\n{}",
        tally.unexplained.len(),
        tally.unexplained.join("\n")
    );
    // Same triangle: each caster's t is within MAX_T_ERR rounding scales (over the cosine of
    // incidence: a grazing hit moves far along the ray for a small error across the plane) of
    // the exact intersection, so the two are too.
    let (eb, ee) = tally.max_err_scaled;
    assert!(
        eb <= MAX_T_ERR && ee <= MAX_T_ERR,
        "{name}: t off the f64 intersection by {eb:.2} (bvh) / {ee:.2} (embree) scales, \
         allowed {MAX_T_ERR}"
    );
    tally
}

/// Same triangle: largest error of either caster's t against the f64 intersection, in
/// rounding scales ([`scale`]) over the cosine of incidence. Embree's t (T times a refined
/// approximate 1/den) and ours (T / den) measured 0.85 at most on both sets below.
const MAX_T_ERR: f64 = 2.0;

#[test]
fn embree_agrees_with_bvh_on_lidar_sweeps_and_random_rays() {
    let (cfg, sim) = default_world();
    let mesh = &sim.world.mesh;
    let bvh = Bvh::build(mesh);
    let embree = EmbreeCaster::build(mesh).expect("Embree builds the default world");

    let lidar = check("lidar sweeps", mesh, &sweeps(&cfg, &sim, &bvh, &embree, 6));
    assert_eq!(lidar.rays, 6 * 1800 * 16, "six full VLP-16 sweeps");
    assert!(
        lidar.hits > lidar.rays / 2,
        "the sweeps see the vineyard: {lidar:?}"
    );
    let random = check(
        "random rays",
        mesh,
        &random_rays(&sim, &bvh, &embree, 200_000),
    );
    assert!(
        random.hits > random.rays / 4,
        "random rays hit something: {random:?}"
    );
    // Disagreements are edge rounding only (checked above) and rare: at most 1 in 10^4 rays.
    for t in [&lidar, &random] {
        assert!(
            t.disagreements() * 10_000 <= t.rays,
            "{} of {} rays disagree: {t:?}",
            t.disagreements(),
            t.rays
        );
    }
}

#[test]
fn embree_answers_do_not_depend_on_the_build() {
    let (cfg, sim) = default_world();
    let mesh = &sim.world.mesh;
    let bvh = Bvh::build(mesh);
    let a = EmbreeCaster::build(mesh).expect("Embree builds");
    let b = EmbreeCaster::build(mesh).expect("Embree builds again");
    let bits = |h: Option<Hit>| h.map(|h| (h.t.to_bits(), h.triangle));
    let sweep_a = sweeps(&cfg, &sim, &bvh, &a, 2);
    let sweep_b = sweeps(&cfg, &sim, &bvh, &b, 2);
    let rand_a = random_rays(&sim, &bvh, &a, 20_000);
    let rand_b = random_rays(&sim, &bvh, &b, 20_000);
    let mut hits = 0;
    for (x, y) in sweep_a
        .iter()
        .zip(&sweep_b)
        .chain(rand_a.iter().zip(&rand_b))
    {
        assert_eq!(
            bits(x.embree),
            bits(y.embree),
            "two builds answer differently"
        );
        hits += usize::from(x.embree.is_some());
    }
    assert!(hits > 10_000, "{hits} hits");
}

#[test]
fn lidar_scans_with_embree_are_identical_across_builds_and_thread_counts() {
    let cfg = SimConfig {
        raycaster: RaycasterKind::Embree,
        ..SimConfig::default()
    };
    let scans = |threads: usize| {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .expect("thread pool");
        pool.install(|| {
            let sim = Simulation::new(&cfg, "s3", 7).expect("s3 builds with Embree");
            let sensors: SensorSet = "lidar,scan2d".parse().expect("sensor list");
            sim.stream(sensors).take(12).collect::<Vec<_>>()
        })
    };
    let one = scans(1);
    let two = scans(2);
    assert_eq!(one.len(), 12);
    assert!(one == two, "lidar/2D scans differ between 1 and 2 threads");
}

#[test]
fn embree_packets_answer_as_single_rays() {
    // The bench offers rtcIntersect4/8/16 for a column's fan; they must give the answers of
    // one rtcIntersect1 per ray, bit for bit.
    let (cfg, sim) = default_world();
    let mesh = &sim.world.mesh;
    let bvh = Bvh::build(mesh);
    let single = EmbreeCaster::with_options(mesh, SceneOptions::default(), Packet::Single)
        .expect("Embree builds");
    let reference = sweeps(&cfg, &sim, &bvh, &single, 2);
    let bits = |h: Option<Hit>| h.map(|h| (h.t.to_bits(), h.triangle));
    for packet in [Packet::X4, Packet::X8, Packet::X16] {
        let caster = EmbreeCaster::with_options(mesh, SceneOptions::default(), packet)
            .expect("Embree builds");
        let cases = sweeps(&cfg, &sim, &bvh, &caster, 2);
        let differ = cases
            .iter()
            .zip(&reference)
            .filter(|(a, b)| bits(a.embree) != bits(b.embree))
            .count();
        assert_eq!(
            differ,
            0,
            "{packet:?}: {differ} of {} rays differ",
            cases.len()
        );
    }
}
