//! Primitive shapes appended to a mesh: tubes (trunks, shoots, wires, posts), leaves and
//! grape bunches.

use nalgebra::{Point3, Vector3};

use super::mesh::{Material, Mesh};

/// Two unit vectors perpendicular to `axis` and to each other.
fn frame(axis: &Vector3<f32>) -> (Vector3<f32>, Vector3<f32>) {
    let helper = if axis.z.abs() < 0.9 {
        Vector3::z()
    } else {
        Vector3::x()
    };
    let u = axis.cross(&helper).normalize();
    let v = axis.cross(&u);
    (u, v)
}

/// An open tube of `sides` flat faces from `a` to `b` (no end caps: rays never see inside).
/// With `cap`, the top end at `b` is closed.
pub fn tube(
    mesh: &mut Mesh,
    a: Point3<f32>,
    b: Point3<f32>,
    radius: f32,
    sides: usize,
    cap: bool,
    material: Material,
) {
    let axis = b - a;
    let Some(dir) = axis.try_normalize(1e-9) else {
        return;
    };
    let (u, v) = frame(&dir);
    let ring = |centre: Point3<f32>, mesh: &mut Mesh| -> u32 {
        let first = mesh.vertices.len() as u32;
        for s in 0..sides {
            let angle = std::f32::consts::TAU * s as f32 / sides as f32;
            mesh.push_vertex(centre + (u * angle.cos() + v * angle.sin()) * radius);
        }
        first
    };
    let ra = ring(a, mesh);
    let rb = ring(b, mesh);
    let n = sides as u32;
    for s in 0..n {
        let t = (s + 1) % n;
        mesh.push_triangle([ra + s, ra + t, rb + t], material);
        mesh.push_triangle([ra + s, rb + t, rb + s], material);
    }
    if cap {
        for s in 1..n - 1 {
            mesh.push_triangle([rb, rb + s, rb + s + 1], material);
        }
    }
}

/// A tube along a polyline (joints share no vertices: a few hundred extra vertices per plant
/// are cheaper than the bookkeeping).
pub fn polyline_tube(
    mesh: &mut Mesh,
    points: &[Point3<f32>],
    radius: f32,
    sides: usize,
    material: Material,
) {
    for pair in points.windows(2) {
        tube(mesh, pair[0], pair[1], radius, sides, false, material);
    }
}

/// A leaf folded along its midrib: a diamond from `base` to `base + length * dir`, its
/// half-width `0.45 * length` along `side`, the two halves raised by `fold` of the width.
pub fn leaf(
    mesh: &mut Mesh,
    base: Point3<f32>,
    dir: Vector3<f32>,
    side: Vector3<f32>,
    length: f32,
    fold: f32,
) {
    let normal = dir.cross(&side);
    let width = 0.45 * length;
    let mid = base + dir * (0.45 * length);
    let tip = mesh.push_vertex(base + dir * length);
    let b = mesh.push_vertex(base);
    let left = mesh.push_vertex(mid + side * width + normal * (fold * width));
    let right = mesh.push_vertex(mid - side * width + normal * (fold * width));
    mesh.push_triangle([b, tip, left], Material::Leaf);
    mesh.push_triangle([b, right, tip], Material::Leaf);
}

/// A grape bunch: an elongated double cone hanging from `top`, as an octahedron of 8 faces.
pub fn bunch(mesh: &mut Mesh, top: Point3<f32>, length: f32, width: f32) {
    let centre = top - Vector3::z() * (0.35 * length);
    let apex = mesh.push_vertex(top);
    let bottom = mesh.push_vertex(top - Vector3::z() * length);
    let r = 0.5 * width;
    let ring: Vec<u32> = [(r, 0.0), (0.0, r), (-r, 0.0), (0.0, -r)]
        .iter()
        .map(|&(dx, dy)| mesh.push_vertex(centre + Vector3::new(dx, dy, 0.0)))
        .collect();
    for s in 0..4 {
        let (p, q) = (ring[s], ring[(s + 1) % 4]);
        mesh.push_triangle([apex, p, q], Material::Grape);
        mesh.push_triangle([bottom, q, p], Material::Grape);
    }
}

/// An axis-aligned box post standing on `base`, `width` square and `height` tall, with a top.
/// Its texture coordinates are relative to `base`, so all posts share one look.
pub fn post(mesh: &mut Mesh, base: Point3<f32>, width: f32, height: f32) {
    // A square tube is a 4-sided tube rotated by 45° so its faces align with the axes.
    let h = 0.5 * width;
    let corners = [(-h, -h), (h, -h), (h, h), (-h, h)];
    let bottom: Vec<u32> = corners
        .iter()
        .map(|&(dx, dy)| mesh.push_vertex_tex(base + Vector3::new(dx, dy, -0.1), [dx, dy, -0.1]))
        .collect();
    let top: Vec<u32> = corners
        .iter()
        .map(|&(dx, dy)| {
            mesh.push_vertex_tex(base + Vector3::new(dx, dy, height), [dx, dy, height])
        })
        .collect();
    for s in 0..4 {
        let t = (s + 1) % 4;
        mesh.push_triangle([bottom[s], bottom[t], top[t]], Material::Post);
        mesh.push_triangle([bottom[s], top[t], top[s]], Material::Post);
    }
    mesh.push_triangle([top[0], top[1], top[2]], Material::Post);
    mesh.push_triangle([top[0], top[2], top[3]], Material::Post);
}

/// An upright box standing on `foot` (the centre of its base; sunk 0.1 m into the ground
/// so no gap shows on a slope), `size` = (length, thickness, height), its length along
/// `yaw` from world x: a fence panel. Texture space is panel-local, like a post's, moved by
/// `tex_offset` (zero: every panel looks the same).
pub fn panel(mesh: &mut Mesh, foot: Point3<f32>, yaw: f32, size: [f32; 3], tex_offset: [f32; 3]) {
    let [l, t, h] = size;
    let (c, s) = (yaw.cos(), yaw.sin());
    let (along, across) = (Vector3::new(c, s, 0.0), Vector3::new(-s, c, 0.0));
    let corner = |i: usize, top: bool| {
        let (a, b) = [(-0.5, -0.5), (0.5, -0.5), (0.5, 0.5), (-0.5, 0.5)][i];
        let z = if top { h } else { -0.1 };
        let local = [a * l, b * t, z];
        (
            foot + along * local[0] + across * local[1] + Vector3::z() * z,
            std::array::from_fn(|k| local[k] + tex_offset[k]),
        )
    };
    let bottom: Vec<u32> = (0..4)
        .map(|i| {
            let (p, tex) = corner(i, false);
            mesh.push_vertex_tex(p, tex)
        })
        .collect();
    let top: Vec<u32> = (0..4)
        .map(|i| {
            let (p, tex) = corner(i, true);
            mesh.push_vertex_tex(p, tex)
        })
        .collect();
    for i in 0..4 {
        let j = (i + 1) % 4;
        mesh.push_triangle([bottom[i], bottom[j], top[j]], Material::Post);
        mesh.push_triangle([bottom[i], top[j], top[i]], Material::Post);
    }
    mesh.push_triangle([top[0], top[1], top[2]], Material::Post);
    mesh.push_triangle([top[0], top[2], top[3]], Material::Post);
}
