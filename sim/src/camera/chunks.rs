//! The mesh cut into spatial chunks (triangles binned by centroid into square cells of the
//! ground plane) with bounding boxes, so a frame only touches the chunks in its frustum.

use std::ops::Range;

use rayon::prelude::*;

use super::raster::{View, cross, dot, sub};
use super::texture::TriConstants;
use crate::world::{Material, Mesh};

/// One triangle with everything shading needs, stored in chunk order.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Tri {
    /// Corners in the world frame.
    pub p: [[f32; 3]; 3],
    /// Corners in texture space (see [`Mesh::tex`]).
    pub t: [[f32; 3]; 3],
    pub material: Material,
    /// Unit normal `(p1 - p0) x (p2 - p0)` (zero for a degenerate triangle).
    pub n: [f32; 3],
    /// Gradients of the barycentric weights of corners 1 and 2 in the triangle's plane:
    /// a point `x` of the plane has weights `g[k] · (x - p0)`.
    pub g: [[f32; 3]; 2],
    pub k: TriConstants,
}

impl Tri {
    fn new(p: [[f32; 3]; 3], t: [[f32; 3]; 3], material: Material) -> Self {
        let e1 = sub(&p[1], &p[0]);
        let e2 = sub(&p[2], &p[0]);
        let n = cross(&e1, &e2);
        let n2 = dot(&n, &n);
        let (unit, g) = if n2 > 0.0 && n2.is_finite() {
            let inv = 1.0 / n2;
            let len = n2.sqrt();
            (
                n.map(|c| c / len),
                [
                    cross(&e2, &n).map(|c| c * inv),
                    cross(&n, &e1).map(|c| c * inv),
                ],
            )
        } else {
            ([0.0; 3], [[0.0; 3]; 2])
        };
        Self {
            p,
            t,
            material,
            n: unit,
            g,
            k: TriConstants::new(material, &t, &g),
        }
    }
}

#[derive(Debug, Clone)]
pub(crate) struct Chunk {
    pub lo: [f32; 3],
    pub hi: [f32; 3],
    pub tris: Range<u32>,
}

#[derive(Debug, Clone)]
pub(crate) struct Chunks {
    pub tris: Vec<Tri>,
    pub chunks: Vec<Chunk>,
}

impl Chunks {
    /// Bins every triangle by its centroid into `cell_m` squares; a chunk's box bounds its
    /// triangles wholly. Triangle order inside a chunk is mesh order.
    pub fn build(mesh: &Mesh, cell_m: f32) -> Self {
        let cell_of = |i: usize| {
            let [a, b, c] = mesh.corners(i);
            let x = (a.x + b.x + c.x) / 3.0;
            let y = (a.y + b.y + c.y) / 3.0;
            (
                (y / cell_m).floor() as i32,
                (x / cell_m).floor() as i32,
                i as u32,
            )
        };
        let mut order: Vec<(i32, i32, u32)> = (0..mesh.triangle_count()).map(cell_of).collect();
        order.par_sort_unstable();
        let tris: Vec<Tri> = order
            .par_iter()
            .map(|&(_, _, i)| {
                let [a, b, c] = mesh.triangles[i as usize];
                let p = [a, b, c].map(|v| {
                    let q = mesh.vertices[v as usize];
                    [q.x, q.y, q.z]
                });
                // A mesh whose texture coordinates were not kept up (only possible by
                // editing its fields directly) is textured by position.
                let t = [a, b, c].map(|v| {
                    mesh.tex.get(v as usize).copied().unwrap_or_else(|| {
                        let q = mesh.vertices[v as usize];
                        [q.x, q.y, q.z]
                    })
                });
                Tri::new(p, t, mesh.materials[i as usize])
            })
            .collect();
        let mut chunks = Vec::new();
        let mut start = 0usize;
        for k in 1..=order.len() {
            if k == order.len() || (order[k].0, order[k].1) != (order[start].0, order[start].1) {
                let mut lo = [f32::INFINITY; 3];
                let mut hi = [f32::NEG_INFINITY; 3];
                for t in &tris[start..k] {
                    for p in &t.p {
                        for d in 0..3 {
                            lo[d] = lo[d].min(p[d]);
                            hi[d] = hi[d].max(p[d]);
                        }
                    }
                }
                chunks.push(Chunk {
                    lo,
                    hi,
                    tris: start as u32..k as u32,
                });
                start = k;
            }
        }
        Self { tris, chunks }
    }

    /// Chunks whose box meets the view frustum, in chunk order.
    pub fn visible(&self, view: &View) -> Vec<Range<u32>> {
        self.chunks
            .iter()
            .filter(|c| view.box_visible(&c.lo, &c.hi))
            .map(|c| c.tris.clone())
            .collect()
    }
}
