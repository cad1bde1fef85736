//! Triangle soup with one material per triangle: the scene every ray sensor sees.

use nalgebra::{Point3, Vector3};

/// What a surface is made of. The lidar uses it for reflectivity; the camera will shade it.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
#[repr(u8)]
pub enum Material {
    Soil = 0,
    Grass = 1,
    Bark = 2,
    Leaf = 3,
    Grape = 4,
    Post = 5,
    Wire = 6,
}

impl Material {
    /// Every material, in discriminant order.
    pub const ALL: [Material; 7] = [
        Material::Soil,
        Material::Grass,
        Material::Bark,
        Material::Leaf,
        Material::Grape,
        Material::Post,
        Material::Wire,
    ];

    /// Diffuse reflectivity at the 905 nm lidar wavelength, in [0, 1] (typical values for
    /// dry soil, vegetation, wood and galvanised steel).
    pub fn nir_reflectivity(self) -> f32 {
        match self {
            Material::Soil => 0.30,
            Material::Grass => 0.45,
            Material::Bark => 0.35,
            Material::Leaf => 0.50,
            Material::Grape => 0.25,
            Material::Post => 0.40,
            Material::Wire => 0.60,
        }
    }

    /// Lower-case name, as used in files and reports.
    pub fn name(self) -> &'static str {
        match self {
            Material::Soil => "soil",
            Material::Grass => "grass",
            Material::Bark => "bark",
            Material::Leaf => "leaf",
            Material::Grape => "grape",
            Material::Post => "post",
            Material::Wire => "wire",
        }
    }
}

/// An indexed triangle mesh in the world frame (metres, z up), one material per triangle.
///
/// `tex[i]` is vertex `i`'s position in texture space, which the camera's procedural
/// materials are evaluated in: the world position for the ground, the position relative to
/// the plant's trunk foot (or the post's foot) for vines and posts. So clones of a plant
/// carry identical texture coordinates wherever they stand and look identical on camera.
#[derive(Debug, Clone, Default)]
pub struct Mesh {
    pub vertices: Vec<Point3<f32>>,
    pub triangles: Vec<[u32; 3]>,
    pub materials: Vec<Material>,
    /// Texture-space position of every vertex (same length as `vertices`).
    pub tex: Vec<[f32; 3]>,
}

impl Mesh {
    pub fn new() -> Self {
        Self::default()
    }

    pub fn triangle_count(&self) -> usize {
        self.triangles.len()
    }

    /// Adds a vertex whose texture-space position is its own position, and returns its index.
    pub fn push_vertex(&mut self, p: Point3<f32>) -> u32 {
        self.push_vertex_tex(p, [p.x, p.y, p.z])
    }

    /// Adds a vertex with an explicit texture-space position and returns its index.
    pub fn push_vertex_tex(&mut self, p: Point3<f32>, tex: [f32; 3]) -> u32 {
        let i = u32::try_from(self.vertices.len()).expect("mesh exceeds u32 vertices");
        self.vertices.push(p);
        self.tex.push(tex);
        i
    }

    pub fn push_triangle(&mut self, tri: [u32; 3], material: Material) {
        self.triangles.push(tri);
        self.materials.push(material);
    }

    /// Appends another mesh, re-indexing its vertices.
    pub fn append(&mut self, other: &Mesh) {
        let base = u32::try_from(self.vertices.len()).expect("mesh exceeds u32 vertices");
        self.vertices.extend_from_slice(&other.vertices);
        self.tex.extend_from_slice(&other.tex);
        self.triangles.extend(
            other
                .triangles
                .iter()
                .map(|t| [t[0] + base, t[1] + base, t[2] + base]),
        );
        self.materials.extend_from_slice(&other.materials);
    }

    /// The three corners of triangle `i`.
    pub fn corners(&self, i: usize) -> [Point3<f32>; 3] {
        let [a, b, c] = self.triangles[i];
        [
            self.vertices[a as usize],
            self.vertices[b as usize],
            self.vertices[c as usize],
        ]
    }

    /// Unit normal of triangle `i` (right-handed winding); zero for a degenerate triangle.
    pub fn normal(&self, i: usize) -> Vector3<f32> {
        let [a, b, c] = self.corners(i);
        (b - a)
            .cross(&(c - a))
            .try_normalize(1e-12)
            .unwrap_or_else(Vector3::zeros)
    }

    /// Axis-aligned bounds `(min, max)`; `None` for an empty mesh.
    pub fn bounds(&self) -> Option<(Point3<f32>, Point3<f32>)> {
        let first = *self.vertices.first()?;
        Some(
            self.vertices
                .iter()
                .fold((first, first), |(lo, hi), p| (lo.inf(p), hi.sup(p))),
        )
    }
}
