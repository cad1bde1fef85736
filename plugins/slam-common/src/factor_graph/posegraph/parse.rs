//! Reading pose-graph files into a [`PoseGraph`].
//!
//! Line kinds (one per line, tokens separated by white space; blank lines and lines
//! starting with `#` are skipped; any other tag is an error naming the line):
//!
//! | tag | fields | source |
//! |---|---|---|
//! | `VERTEX_SE3:QUAT` | `id x y z qx qy qz qw` | g2o `VertexSE3` |
//! | `VERTEX3` | `id x y z roll pitch yaw` | TORO 3D |
//! | `EDGE_SE3:QUAT` | `a b x y z qx qy qz qw` + 21 information values | g2o `EdgeSE3` |
//! | `EDGE3` | `a b x y z roll pitch yaw` + 21 information values | TORO 3D |
//! | `VERTEX2`, `VERTEX_SE2` | `id x y θ` | TORO, g2o `VertexSE2` |
//! | `EDGE2` | `a b dx dy dθ I11 I12 I22 I33 I13 I23` | TORO 2D |
//! | `EDGE_SE2` | `a b dx dy dθ I11 I12 I13 I22 I23 I33` | g2o `EdgeSE2` |
//! | `EQUIV` | `a b` | TORO: ignored, as GTSAM's reader ignores it |
//!
//! Conventions, as GTSAM's `gtsam/slam/dataset.cpp` (`readG2o`, `load2D`, `load3D`) has
//! them, so that a graph read here is the graph GTSAM reads:
//! - Quaternions are `qx qy qz qw` and are normalised.
//! - TORO's 3D rotation `roll pitch yaw` is `Rot3::Ypr(yaw, pitch, roll)` =
//!   Rz(yaw)·Ry(pitch)·Rx(roll).
//! - Information matrices are the upper triangle, row by row. g2o's `EDGE_SE3:QUAT`
//!   orders it translation then rotation; it is permuted to our (and GTSAM's) rotation
//!   first. TORO's `EDGE3` is taken **as is**, i.e. rotation first, exactly as GTSAM's
//!   reader does (it does not permute EDGE3's matrix although TORO writes x y z first): for
//!   sphere2500 (`10 … 10 … 10 … 100 … 100 … 25`) that means rotation sigmas 1/√10 rad
//!   and translation sigmas 0.1, 0.1, 0.2 m.
//! - TORO's `EDGE2` information order is `I11 I12 I22 I33 I13 I23` (x, y, θ; OpenSLAM's
//!   TORO documentation, GTSAM's `NoiseFormatTORO`); g2o's `EDGE_SE2` is the plain upper
//!   triangle. (GTSAM's `load2D` in its default "auto" mode guesses that w10000's
//!   `1 0 1 1 0 0` is a covariance; it is the identity, so both readings agree.)
//! - An edge `a b z` is `BetweenFactor(a, b, z)`: `z` is `a⁻¹·b`.
//!
//! Information must be diagonal: [`Factor::Between`](crate::factor_graph::backend::Factor) takes
//! diagonal sigmas, and every GTSAM benchmark graph (pose3example, sphere2500, w10000,
//! City10000) has diagonal information, so sigmas are `1/√diag(info)` and an off-diagonal
//! entry is an error rather than a silent approximation.
//!
//! Planar files are lifted to SE(3): z = 0, roll = pitch = 0, yaw = θ, and every edge's
//! missing dimensions (z, roll, pitch) get the sigma [`LIFT_SIGMA`]; the same for every
//! backend. The SE(3) logarithm of a planar motion is GTSAM's `Pose2::Logmap` padded with
//! zeros, so on planar estimates the lifted graph's error is the Pose2 graph's error with
//! exact logarithms.
//!
//! GTSAM's City10000 file (`T1_city10000_04.txt`, used by its `ISAM2_City10000.cpp`
//! example) has its own layout: `EDGE2 s _ t _ k` then `k` hypotheses `dx dy dθ`; the
//! example uses the first hypothesis, a fixed noise (σ = 1/30 m, 1/30 m, 1/100 rad) and
//! no vertices, and so does this reader. [`Format::Auto`] recognises it by its first
//! `EDGE2` line (`5 + 3k` fields, `k` the fifth, rather than TORO's 11).
//!
//! The first pose is anchored by a prior (see [`PoseGraph::prior`]) with the sigmas of
//! the GTSAM example for the kind of file: spatial graphs [`PRIOR_SIGMAS_3D`]
//! (`Pose3SLAMExample_g2o.cpp`: variances 1e-6 rad², 1e-4 m²), planar TORO/g2o graphs
//! [`PRIOR_SIGMAS_2D`] (`Pose2SLAMExample_g2o.cpp`: variances 1e-6 m², 1e-6 m², 1e-8
//! rad²), City10000 [`PRIOR_SIGMAS_CITY`] (`ISAM2_City10000.cpp`: σ = 1e-4), planar ones
//! with [`LIFT_SIGMA`] on z, roll and pitch.

use std::collections::BTreeMap;
use std::path::Path;

use nalgebra::{Isometry3, Quaternion, Translation3, UnitQuaternion, Vector3};

use super::{Edge, PoseGraph, PoseGraphError};
use crate::factor_graph::backend::PoseSigmas;

/// Sigma (m for z, rad for roll and pitch) of the dimensions a planar graph does not
/// have, in its lifted edges and prior: tight against every planar sigma of the GTSAM
/// datasets (≥ 1/100).
pub const LIFT_SIGMA: f64 = 1e-3;

/// Prior sigmas for spatial graphs: rotation 1e-3 rad, translation 1e-2 m.
pub const PRIOR_SIGMAS_3D: [f64; 6] = [1e-3, 1e-3, 1e-3, 1e-2, 1e-2, 1e-2];
/// Prior sigmas for planar TORO/g2o graphs (roll, pitch, yaw, x, y, z).
pub const PRIOR_SIGMAS_2D: [f64; 6] = [LIFT_SIGMA, LIFT_SIGMA, 1e-4, 1e-3, 1e-3, LIFT_SIGMA];
/// Prior sigmas for City10000 (roll, pitch, yaw, x, y, z).
pub const PRIOR_SIGMAS_CITY: [f64; 6] = [LIFT_SIGMA, LIFT_SIGMA, 1e-4, 1e-4, 1e-4, LIFT_SIGMA];
/// City10000's between sigmas in the plane (x, y, θ).
pub const CITY_SIGMAS: [f64; 3] = [1.0 / 30.0, 1.0 / 30.0, 1.0 / 100.0];

/// Which layout a file has.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Format {
    /// City10000 if the first `EDGE2` line has City10000's shape, else g2o/TORO.
    #[default]
    Auto,
    /// g2o and TORO tagged lines.
    G2o,
    /// GTSAM's City10000 edge list.
    City10000,
}

/// Reads and parses a file (errors name it and the line).
pub fn read(path: &Path, format: Format) -> Result<PoseGraph, PoseGraphError> {
    let text = std::fs::read_to_string(path).map_err(|source| PoseGraphError::Io {
        path: path.display().to_string(),
        source,
    })?;
    parse(&path.display().to_string(), &text, format)
}

/// Parses a file's text; `name` is what errors call it.
pub fn parse(name: &str, text: &str, format: Format) -> Result<PoseGraph, PoseGraphError> {
    let format = match format {
        Format::Auto => detect(text),
        f => f,
    };
    let mut p = Parser {
        graph: PoseGraph {
            planar: false,
            vertices: BTreeMap::new(),
            edges: Vec::new(),
            prior_sigmas: PoseSigmas::from(PRIOR_SIGMAS_3D),
        },
        planar: None,
    };
    for (i, raw) in text.lines().enumerate() {
        let line = raw.trim();
        if line.is_empty() || line.starts_with('#') {
            continue;
        }
        let mut f = Fields {
            name,
            line: i + 1,
            tokens: line.split_whitespace(),
            tag: "",
        };
        f.tag = f.tokens.next().unwrap_or_default();
        match format {
            Format::City10000 => p.city(&mut f)?,
            _ => p.tagged(&mut f)?,
        }
    }
    let planar = p.planar.unwrap_or(false);
    p.graph.planar = planar;
    p.graph.prior_sigmas = PoseSigmas::from(match (format, planar) {
        (Format::City10000, _) => PRIOR_SIGMAS_CITY,
        (_, true) => PRIOR_SIGMAS_2D,
        (_, false) => PRIOR_SIGMAS_3D,
    });
    if p.graph.keys().is_empty() {
        return Err(PoseGraphError::Graph(format!("{name}: no poses")));
    }
    Ok(p.graph)
}

/// A ground-truth trajectory: either lines of `x y θ` (pose i on the i-th line, as
/// `ISAM2_GT_city10000.txt`), or a graph file whose vertices are the truth, or whose
/// edges chain to it when it has none (as `sphere2500_groundtruth.txt`, noise-free edges).
/// Returns whether it is planar, and the poses by key.
pub fn read_trajectory(
    path: &Path,
) -> Result<(bool, BTreeMap<u64, Isometry3<f64>>), PoseGraphError> {
    let name = path.display().to_string();
    let text = std::fs::read_to_string(path).map_err(|source| PoseGraphError::Io {
        path: name.clone(),
        source,
    })?;
    let first = text
        .split_whitespace()
        .next()
        .ok_or_else(|| PoseGraphError::Graph(format!("{name}: empty")))?;
    if first.parse::<f64>().is_err() {
        let g = parse(&name, &text, Format::Auto)?;
        let poses = if g.vertices.is_empty() {
            g.initial_guess()
        } else {
            g.vertices.clone()
        };
        return Ok((g.planar, poses));
    }
    let mut poses = BTreeMap::new();
    for (i, raw) in text.lines().enumerate() {
        if raw.trim().is_empty() {
            continue;
        }
        let mut f = Fields {
            name: &name,
            line: i + 1,
            tokens: raw.split_whitespace(),
            tag: "x y θ",
        };
        let (x, y, th) = (f.num("x")?, f.num("y")?, f.num("θ")?);
        f.end()?;
        poses.insert(poses.len() as u64, planar_pose(x, y, th));
    }
    Ok((true, poses))
}

fn detect(text: &str) -> Format {
    let first_edge2 = text.lines().find_map(|l| {
        let t: Vec<&str> = l.split_whitespace().collect();
        (t.first() == Some(&"EDGE2")).then_some(t)
    });
    match first_edge2 {
        Some(t) if is_city(&t[1..]) => Format::City10000,
        _ => Format::G2o,
    }
}

fn is_city(f: &[&str]) -> bool {
    f.len() != 11
        && f.len() >= 8
        && f[4].parse::<usize>().is_ok_and(|k| {
            k >= 1 && k.checked_mul(3).and_then(|n| n.checked_add(5)) == Some(f.len())
        })
}

/// `(x, y, θ)` lifted: z = 0, yaw = θ.
pub fn planar_pose(x: f64, y: f64, theta: f64) -> Isometry3<f64> {
    Isometry3::new(Vector3::new(x, y, 0.0), Vector3::new(0.0, 0.0, theta))
}

/// Planar sigmas `(x, y, θ)` lifted to our rotation-first six.
pub fn planar_sigmas(sx: f64, sy: f64, st: f64) -> PoseSigmas {
    PoseSigmas::new(LIFT_SIGMA, LIFT_SIGMA, st, sx, sy, LIFT_SIGMA)
}

struct Parser {
    graph: PoseGraph,
    /// Whether the lines seen so far were planar (None before the first pose line).
    planar: Option<bool>,
}

impl Parser {
    fn kind(&mut self, f: &Fields, planar: bool) -> Result<(), PoseGraphError> {
        match self.planar {
            Some(p) if p != planar => Err(f.err(format!(
                "{} mixes planar and spatial lines in one graph",
                f.tag
            ))),
            _ => {
                self.planar = Some(planar);
                Ok(())
            }
        }
    }

    fn vertex(&mut self, f: &Fields, id: u64, pose: Isometry3<f64>) -> Result<(), PoseGraphError> {
        if self.graph.vertices.insert(id, pose).is_some() {
            return Err(f.err(format!("vertex {id} given twice")));
        }
        Ok(())
    }

    fn edge(
        &mut self,
        f: &Fields,
        from: u64,
        to: u64,
        z: Isometry3<f64>,
        sigmas: PoseSigmas,
    ) -> Result<(), PoseGraphError> {
        if from == to {
            return Err(f.err(format!("edge from pose {from} to itself")));
        }
        self.graph.edges.push(Edge {
            from,
            to,
            from_from_to: z,
            sigmas,
            line: f.line,
        });
        Ok(())
    }

    fn tagged(&mut self, f: &mut Fields) -> Result<(), PoseGraphError> {
        match f.tag {
            "VERTEX_SE3:QUAT" => {
                self.kind(f, false)?;
                let id = f.id()?;
                let pose = f.quat_pose()?;
                f.end()?;
                self.vertex(f, id, pose)
            }
            "VERTEX3" => {
                self.kind(f, false)?;
                let id = f.id()?;
                let pose = f.rpy_pose()?;
                f.end()?;
                self.vertex(f, id, pose)
            }
            "EDGE_SE3:QUAT" => {
                self.kind(f, false)?;
                let (a, b) = (f.id()?, f.id()?);
                let z = f.quat_pose()?;
                // g2o: translation then rotation; ours: rotation then translation.
                let d = f.diagonal_information(6)?;
                f.end()?;
                let s = |i: usize| 1.0 / d[i].sqrt();
                self.edge(
                    f,
                    a,
                    b,
                    z,
                    PoseSigmas::new(s(3), s(4), s(5), s(0), s(1), s(2)),
                )
            }
            "EDGE3" => {
                self.kind(f, false)?;
                let (a, b) = (f.id()?, f.id()?);
                let z = f.rpy_pose()?;
                // As GTSAM's reader: no permutation (see the module documentation).
                let d = f.diagonal_information(6)?;
                f.end()?;
                let s = |i: usize| 1.0 / d[i].sqrt();
                self.edge(
                    f,
                    a,
                    b,
                    z,
                    PoseSigmas::new(s(0), s(1), s(2), s(3), s(4), s(5)),
                )
            }
            "VERTEX2" | "VERTEX_SE2" => {
                self.kind(f, true)?;
                let id = f.id()?;
                let (x, y, th) = (f.num("x")?, f.num("y")?, f.num("θ")?);
                f.end()?;
                self.vertex(f, id, planar_pose(x, y, th))
            }
            "EDGE2" | "EDGE_SE2" => {
                self.kind(f, true)?;
                let (a, b) = (f.id()?, f.id()?);
                let (x, y, th) = (f.num("dx")?, f.num("dy")?, f.num("dθ")?);
                let v = f.nums::<6>("information")?;
                f.end()?;
                // Full symmetric matrix in x, y, θ order from the file's layout.
                let m = if f.tag == "EDGE2" {
                    [[v[0], v[1], v[4]], [v[1], v[2], v[5]], [v[4], v[5], v[3]]]
                } else {
                    [[v[0], v[1], v[2]], [v[1], v[3], v[4]], [v[2], v[4], v[5]]]
                };
                let d = f.check_diagonal(&m)?;
                let s = |i: usize| 1.0 / d[i].sqrt();
                self.edge(
                    f,
                    a,
                    b,
                    planar_pose(x, y, th),
                    planar_sigmas(s(0), s(1), s(2)),
                )
            }
            "EQUIV" => Ok(()),
            other => Err(f.err(format!("unsupported line kind {other:?}"))),
        }
    }

    fn city(&mut self, f: &mut Fields) -> Result<(), PoseGraphError> {
        if f.tag != "EDGE2" {
            return Err(f.err(format!("City10000 file: expected EDGE2, found {:?}", f.tag)));
        }
        self.kind(f, true)?;
        let from = f.id()?;
        f.id()?;
        let to = f.id()?;
        f.id()?;
        let k = f.id()?;
        if k == 0 {
            return Err(f.err("City10000 EDGE2 with no measurement".to_string()));
        }
        let (x, y, th) = (f.num("dx")?, f.num("dy")?, f.num("dθ")?);
        for _ in 1..k {
            f.nums::<3>("further hypothesis")?;
        }
        f.end()?;
        let [sx, sy, st] = CITY_SIGMAS;
        self.edge(
            f,
            from,
            to,
            planar_pose(x, y, th),
            planar_sigmas(sx, sy, st),
        )
    }
}

struct Fields<'a> {
    name: &'a str,
    line: usize,
    tokens: std::str::SplitWhitespace<'a>,
    tag: &'a str,
}

impl<'a> Fields<'a> {
    fn err(&self, message: String) -> PoseGraphError {
        PoseGraphError::Line {
            path: self.name.to_string(),
            line: self.line,
            message,
        }
    }

    fn token(&mut self, what: &str) -> Result<&'a str, PoseGraphError> {
        match self.tokens.next() {
            Some(t) => Ok(t),
            None => Err(self.err(format!("{}: missing {what}", self.tag))),
        }
    }

    fn id(&mut self) -> Result<u64, PoseGraphError> {
        let t = self.token("pose id")?;
        t.parse()
            .map_err(|_| self.err(format!("{}: bad pose id {t:?}", self.tag)))
    }

    fn num(&mut self, what: &str) -> Result<f64, PoseGraphError> {
        let t = self.token(what)?;
        match t.parse::<f64>() {
            Ok(x) if x.is_finite() => Ok(x),
            _ => Err(self.err(format!("{}: bad {what} {t:?}", self.tag))),
        }
    }

    fn nums<const N: usize>(&mut self, what: &str) -> Result<[f64; N], PoseGraphError> {
        let mut out = [0.0; N];
        for x in &mut out {
            *x = self.num(what)?;
        }
        Ok(out)
    }

    fn end(&mut self) -> Result<(), PoseGraphError> {
        match self.tokens.next() {
            None => Ok(()),
            Some(t) => Err(self.err(format!("{}: unexpected extra field {t:?}", self.tag))),
        }
    }

    /// `x y z qx qy qz qw`, the quaternion normalised.
    fn quat_pose(&mut self) -> Result<Isometry3<f64>, PoseGraphError> {
        let [x, y, z, qx, qy, qz, qw] = self.nums::<7>("pose")?;
        let q = Quaternion::new(qw, qx, qy, qz);
        // Too large a quaternion overflows its norm: normalised, it would be all zeros.
        if !(q.norm() >= 1e-9 && q.norm().is_finite()) {
            return Err(self.err(format!(
                "{}: quaternion of norm {}, not a rotation",
                self.tag,
                q.norm()
            )));
        }
        Ok(Isometry3::from_parts(
            Translation3::new(x, y, z),
            UnitQuaternion::from_quaternion(q),
        ))
    }

    /// `x y z roll pitch yaw`: rotation Rz(yaw)·Ry(pitch)·Rx(roll) (GTSAM's `Rot3::Ypr`).
    fn rpy_pose(&mut self) -> Result<Isometry3<f64>, PoseGraphError> {
        let [x, y, z, roll, pitch, yaw] = self.nums::<6>("pose")?;
        Ok(Isometry3::from_parts(
            Translation3::new(x, y, z),
            UnitQuaternion::from_euler_angles(roll, pitch, yaw),
        ))
    }

    /// The diagonal of an `n`×`n` information matrix given as its upper triangle row by
    /// row; an error if it is not diagonal or not positive.
    fn diagonal_information(&mut self, n: usize) -> Result<Vec<f64>, PoseGraphError> {
        let upper = (0..n * (n + 1) / 2)
            .map(|_| self.num("information value"))
            .collect::<Result<Vec<f64>, _>>()?;
        // Row r of the upper triangle starts after Σ_{k<r} (n − k) = r(2n − r + 1)/2 values.
        let at = |r: usize, c: usize| upper[r * (2 * n - r + 1) / 2 + (c - r)];
        let m: Vec<Vec<f64>> = (0..n)
            .map(|i| (0..n).map(|j| at(i.min(j), i.max(j))).collect())
            .collect();
        self.check_diagonal(&m)
    }

    fn check_diagonal<R: AsRef<[f64]>>(&self, m: &[R]) -> Result<Vec<f64>, PoseGraphError> {
        for (i, row) in m.iter().enumerate() {
            for (j, &v) in row.as_ref().iter().enumerate() {
                if i != j && v != 0.0 {
                    return Err(self.err(format!(
                        "{}: non-diagonal information (entry ({i},{j}) = {v}) is not \
                         supported: between factors take diagonal sigmas",
                        self.tag
                    )));
                }
            }
        }
        let d: Vec<f64> = m.iter().enumerate().map(|(i, r)| r.as_ref()[i]).collect();
        if let Some(v) = d.iter().find(|&&v| v <= 0.0) {
            return Err(self.err(format!(
                "{}: information diagonal must be positive, found {v}",
                self.tag
            )));
        }
        Ok(d)
    }
}
