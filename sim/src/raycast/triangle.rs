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

/// Lanes of a [`TriBlock`]: the most triangles a BVH leaf holds.
pub(crate) const BLOCK: usize = 8;

/// The triangles of one BVH leaf side by side (`v0[axis][lane]` and so on), so a SIMD kernel
/// tests them all at once; lanes past `len` are empty (zero normal: no ray hits them) and
/// carry the id `u32::MAX`.
#[derive(Debug, Clone, Copy, PartialEq)]
#[repr(C, align(64))]
pub(crate) struct TriBlock {
    pub v0: [[f32; BLOCK]; 3],
    pub e1: [[f32; BLOCK]; 3],
    pub e2: [[f32; BLOCK]; 3],
    pub n: [[f32; BLOCK]; 3],
    /// Mesh index of each lane's triangle.
    pub id: [u32; BLOCK],
}

impl TriBlock {
    /// A block of `tris` (at most [`BLOCK`]) with their mesh indices.
    pub fn new(tris: &[Triangle], ids: &[u32]) -> Self {
        assert!(
            tris.len() <= BLOCK && tris.len() == ids.len(),
            "a block holds at most {BLOCK} triangles, one id each"
        );
        let mut block = TriBlock {
            v0: [[0.0; BLOCK]; 3],
            e1: [[0.0; BLOCK]; 3],
            e2: [[0.0; BLOCK]; 3],
            n: [[0.0; BLOCK]; 3],
            id: [u32::MAX; BLOCK],
        };
        for (lane, (t, &id)) in tris.iter().zip(ids).enumerate() {
            for k in 0..3 {
                block.v0[k][lane] = t.v0[k];
                block.e1[k][lane] = t.e1[k];
                block.e2[k][lane] = t.e2[k];
                block.n[k][lane] = t.n[k];
            }
            block.id[lane] = id;
        }
        block
    }

    /// The triangle in `lane`, exactly as it was stored.
    #[inline(always)]
    pub fn get(&self, lane: usize) -> Triangle {
        Triangle {
            v0: std::array::from_fn(|k| self.v0[k][lane]),
            e1: std::array::from_fn(|k| self.e1[k][lane]),
            e2: std::array::from_fn(|k| self.e2[k][lane]),
            n: std::array::from_fn(|k| self.n[k][lane]),
        }
    }
}
