//! Ray–triangle intersection on precomputed triangle data.
//!
//! The test is Möller & Trumbore (1997, "Fast, minimum storage ray/triangle intersection")
//! solved by Cramer's rule with the geometric normal stored per triangle, as in Embree's
//! Möller variant: one cross product per ray and triangle, and the division only once the
//! barycentric test has passed.

use super::aabb::Aabb;
use super::ray::Ray;
use crate::world::Mesh;

/// The mesh's triangles that rays can hit: (mesh index, corners, precomputed triangle),
/// degenerate ones left out. Every caster builds from this, so they agree on what exists.
pub(crate) fn hittable(mesh: &Mesh) -> impl Iterator<Item = (u32, [[f32; 3]; 3], Triangle)> + '_ {
    (0..mesh.triangles.len()).filter_map(|i| {
        let [a, b, c] = mesh.corners(i).map(|p| <[f32; 3]>::from(p.coords));
        let id = u32::try_from(i).expect("mesh exceeds u32 triangles");
        Triangle::new(a, b, c).map(|t| (id, [a, b, c], t))
    })
}

/// `|cos|` of the angle between ray and triangle plane below which the ray counts as parallel
/// to the triangle and misses it (grazing angles under about 1e-6 rad).
pub(crate) const PARALLEL_COS: f32 = 1e-6;

#[inline(always)]
fn sub(a: &[f32; 3], b: &[f32; 3]) -> [f32; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

#[inline(always)]
fn dot(a: &[f32; 3], b: &[f32; 3]) -> f32 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

#[inline(always)]
fn cross(a: &[f32; 3], b: &[f32; 3]) -> [f32; 3] {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

/// A triangle `v0 + u e1 + v e2` (u, v >= 0, u + v <= 1) ready for intersection: the edges are
/// divided by `|e1 x e2|` and `n` is the unit normal, so `d . n` is directly the cosine
/// between ray and normal.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Triangle {
    v0: [f32; 3],
    e1: [f32; 3],
    e2: [f32; 3],
    n: [f32; 3],
}

impl Triangle {
    /// `None` for a degenerate (zero-area or non-finite) triangle, which no ray can hit.
    pub fn new(a: [f32; 3], b: [f32; 3], c: [f32; 3]) -> Option<Self> {
        let e1 = sub(&b, &a);
        let e2 = sub(&c, &a);
        let n = cross(&e1, &e2);
        let len = dot(&n, &n).sqrt();
        if !(len.is_finite() && len > 0.0 && a.iter().all(|x| x.is_finite())) {
            return None;
        }
        let inv = 1.0 / len;
        let scale = |v: [f32; 3]| [v[0] * inv, v[1] * inv, v[2] * inv];
        Some(Self {
            v0: a,
            e1: scale(e1),
            e2: scale(e2),
            n: scale(n),
        })
    }

    /// Bounds of the corners a, b, c the triangle was made from.
    pub fn bounds(a: &[f32; 3], b: &[f32; 3], c: &[f32; 3]) -> Aabb {
        Aabb::of_points(&[*a, *b, *c])
    }

    /// Distance along the ray to the triangle (edges and corners included), or `None` if the
    /// ray misses it or is parallel to it. Not clipped to any interval.
    #[inline(always)]
    pub fn intersect(&self, ray: &Ray) -> Option<f32> {
        // o + t d = v0 + u e1 + v e2. With c = v0 - o, r = d x c and den = d . (e1 x e2):
        // t = (c . n) / den, u = -(e2 . r) / den, v = (e1 . r) / den.
        let den = dot(&ray.d, &self.n);
        let c = sub(&self.v0, &ray.o);
        let r = cross(&ray.d, &c);
        let abs_den = den.abs();
        let sign = if den < 0.0 { -1.0 } else { 1.0 };
        let u = -dot(&self.e2, &r) * sign;
        let v = dot(&self.e1, &r) * sign;
        // `&` rather than `&&`: one branch instead of four hard-to-predict ones.
        let inside = (abs_den > PARALLEL_COS) & (u >= 0.0) & (v >= 0.0) & (u + v <= abs_den);
        if !inside {
            return None;
        }
        Some(dot(&c, &self.n) / den)
    }
}

/// Floats a triangle stores: `v0`, `e1`, `e2` and `n`, three each.
const ROWS: usize = 12;
/// Most triangles in a BVH leaf: one SIMD register (AVX2) of each row.
pub(crate) const BLOCK: usize = 8;

/// The triangles of every BVH leaf, leaf after leaf, each leaf stored row by row (a structure
/// of arrays per leaf): for the leaf of `n` triangles from `first` in leaf order, row `r`
/// (`v0.x, v0.y, v0.z, e1.x, ..., n.z`) holds its `n` values from `ROWS * first + r * n`. A
/// SIMD kernel loads a row as [`BLOCK`] lanes at once, the lanes past `n` being whatever
/// follows (never used); padding at the end keeps every load in bounds. 52 bytes a triangle
/// with its id, as for an array of [`Triangle`]s, however full the leaves are.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct LeafTriangles {
    data: Vec<f32>,
    /// Mesh index of each triangle, in leaf order.
    ids: Vec<u32>,
}

impl LeafTriangles {
    /// `tris` and their mesh `ids`, stored in leaf order `order` (`order[i]`: the index in
    /// `tris` of the triangle `i`-th in leaf order), and the leaves `(first, n)`, which must
    /// cover them exactly.
    pub fn new(tris: &[Triangle], ids: &[u32], order: &[u32], leaves: &[(usize, usize)]) -> Self {
        assert!(
            tris.len() == ids.len()
                && order.len() == tris.len()
                && leaves.iter().map(|l| l.1).sum::<usize>() == tris.len(),
            "the leaves must cover the triangles, one id each"
        );
        let mut data = vec![0.0; ROWS * tris.len() + BLOCK];
        for &(first, n) in leaves {
            for (lane, &src) in order[first..first + n].iter().enumerate() {
                let t = &tris[src as usize];
                for (a, v) in [t.v0, t.e1, t.e2, t.n].iter().enumerate() {
                    for (k, &x) in v.iter().enumerate() {
                        data[ROWS * first + (3 * a + k) * n + lane] = x;
                    }
                }
            }
        }
        Self {
            data,
            ids: order.iter().map(|&k| ids[k as usize]).collect(),
        }
    }

    /// Row `r` of the leaf of `n` triangles from `first`: [`BLOCK`] values, the first `n`
    /// of them the leaf's.
    #[inline(always)]
    pub fn row(&self, first: usize, n: usize, r: usize) -> &[f32; BLOCK] {
        let at = ROWS * first + r * n;
        self.data[at..at + BLOCK]
            .try_into()
            .expect("BLOCK values: the data is padded")
    }

    /// Triangle `lane` of the leaf of `n` triangles from `first`, exactly as it was stored.
    #[inline(always)]
    pub fn get(&self, first: usize, n: usize, lane: usize) -> Triangle {
        let at =
            |a: usize| -> [f32; 3] { std::array::from_fn(|k| self.row(first, n, 3 * a + k)[lane]) };
        Triangle {
            v0: at(0),
            e1: at(1),
            e2: at(2),
            n: at(3),
        }
    }

    /// Mesh index of triangle `i` in leaf order.
    #[inline(always)]
    pub fn id(&self, i: usize) -> u32 {
        self.ids[i]
    }

    /// Triangles stored.
    pub fn len(&self) -> usize {
        self.ids.len()
    }
}
