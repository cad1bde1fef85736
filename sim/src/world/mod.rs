//! The vineyard: terrain, trellis and vines as one triangle mesh with materials.

mod mesh;
mod shapes;
mod survey;
mod terrain;
mod trellis;
mod vine;

use std::ops::Range;

use nalgebra::{Point3, Vector3};
use rand::Rng as _;
use rayon::prelude::*;

pub use mesh::{Material, Mesh};
pub use survey::SurveyedGrid;
pub use terrain::Terrain;
pub use trellis::post_xs;
pub use vine::{PlantRng, VineLayout, vine};

use crate::config::{FenceConfig, SimConfig, TerrainConfig, VineyardConfig};
use crate::rng::stream;

/// One vine's place in the world and its triangles in [`World::mesh`].
#[derive(Debug, Clone)]
pub struct PlantSite {
    pub row: usize,
    pub index: usize,
    /// Trunk foot on the ground, world frame.
    pub base: Point3<f64>,
    pub triangles: Range<usize>,
}

/// The built world.
#[derive(Debug, Clone)]
pub struct World {
    pub vineyard: VineyardConfig,
    pub terrain: Terrain,
    pub mesh: Mesh,
    pub plants: Vec<PlantSite>,
    /// Ground points of every post, row by row (segment by segment).
    pub posts: Vec<Point3<f64>>,
    /// Ground centres of the fence panels.
    pub fence: Vec<Point3<f64>>,
    /// The fence panels' triangles in `mesh` (they follow the block's): a hit there is on
    /// the fence, whose wood shares the trellis posts' material.
    pub fence_triangles: Range<usize>,
    /// Extent of the modelled ground: its lowest corner `[x, y]` and its highest `[x, y]`.
    pub extent: ([f64; 2], [f64; 2]),
}

impl World {
    /// Builds the whole world of a configuration: block, terrain and fence.
    pub fn from_config(cfg: &SimConfig) -> Self {
        Self::build_with_fence(&cfg.vineyard, &cfg.terrain, &cfg.fence, cfg.world_seed)
    }

    /// Builds the world deterministically from its configuration and `world_seed` (no fence).
    pub fn build(vineyard: &VineyardConfig, terrain_cfg: &TerrainConfig, world_seed: u64) -> Self {
        Self::build_with_fence(vineyard, terrain_cfg, &FenceConfig::default(), world_seed)
    }

    fn build_with_fence(
        vineyard: &VineyardConfig,
        terrain_cfg: &TerrainConfig,
        fence: &FenceConfig,
        world_seed: u64,
    ) -> Self {
        let mut terrain = Terrain::new(terrain_cfg, &mut stream(world_seed, "terrain"));
        if let Some(margin) = terrain_cfg.relief_margin_m {
            let (lo, hi) = block_bounds(vineyard);
            let grow = vineyard.headland_m + margin;
            terrain = terrain.windowed([lo[0] - grow, lo[1] - grow], [hi[0] + grow, hi[1] + grow]);
        }
        let mut world = Self::build_on(vineyard, terrain_cfg, terrain, world_seed);
        let [length, thickness, height] = fence.panel_size_m;
        let mut textures = stream(world_seed, "fence/texture");
        let first_fence_triangle = world.mesh.triangles.len();
        for &[x, y, yaw_deg] in &fence.panels {
            let foot = Point3::new(x, y, world.terrain.height(x, y));
            // Drawn only when asked, so a fence of identical panels leaves every other
            // stream of the world as it was.
            let tex_offset = if fence.distinct_panels {
                std::array::from_fn(|_| textures.random_range(0.0f32..50.0))
            } else {
                [0.0; 3]
            };
            shapes::panel(
                &mut world.mesh,
                foot.cast(),
                yaw_deg.to_radians() as f32,
                [length as f32, thickness as f32, height as f32],
                tex_offset,
            );
            world.fence.push(foot);
        }
        world.fence_triangles = first_fence_triangle..world.mesh.triangles.len();
        world
    }

    /// Builds the world on a given terrain surface (tests use [`Terrain::flat`]).
    pub fn build_on(
        vineyard: &VineyardConfig,
        terrain_cfg: &TerrainConfig,
        terrain: Terrain,
        world_seed: u64,
    ) -> Self {
        if !vineyard.segments.is_empty() {
            return Self::build_segments(vineyard, terrain_cfg, terrain, world_seed);
        }
        let v = vineyard;
        // Tilled soil under the rows and lanes, grass on the headlands and beyond.
        let (mut mesh, extent) = ground(v, terrain_cfg, &terrain, [0.5, 1.0]);
        let mut posts = Vec::new();
        for row in 0..v.rows {
            posts.extend(trellis::row_trellis(
                &mut mesh,
                v,
                &terrain,
                row as f64 * v.row_spacing_m,
            ));
        }

        let layout = vine_layout(v, v.plant_spacing_m);
        let per_row = (v.row_length_m / v.plant_spacing_m).floor() as usize;
        let sites: Vec<(usize, usize)> = (0..v.rows)
            .flat_map(|r| (0..per_row).map(move |i| (r, i)))
            .collect();
        let clone_seed = stream(world_seed, "plant/clone");
        let local_meshes: Vec<Mesh> = if v.plant_variation == 0.0 {
            // Identical clones: build once.
            let one = vine(
                &layout,
                &mut PlantRng::new(clone_seed.clone(), clone_seed, 0.0),
            );
            vec![one; sites.len()]
        } else {
            sites
                .par_iter()
                .map(|&(r, i)| {
                    let own = stream(world_seed, &format!("plant/{r}/{i}"));
                    vine(
                        &layout,
                        &mut PlantRng::new(clone_seed.clone(), own, v.plant_variation),
                    )
                })
                .collect()
        };

        let mut plants = Vec::with_capacity(sites.len());
        for (&(row, index), local) in sites.iter().zip(&local_meshes) {
            let x = (index as f64 + 0.5) * v.plant_spacing_m;
            let y = row as f64 * v.row_spacing_m;
            let base = Point3::new(x, y, terrain.height(x, y));
            let offset: Vector3<f32> = base.coords.cast();
            let start = mesh.triangle_count();
            // Moved into place; texture coordinates stay plant-local (see `Mesh::tex`).
            let mut placed = local.clone();
            placed.vertices.iter_mut().for_each(|p| *p += offset);
            mesh.append(&placed);
            plants.push(PlantSite {
                row,
                index,
                base,
                triangles: start..mesh.triangle_count(),
            });
        }

        Self {
            vineyard: v.clone(),
            terrain,
            mesh,
            plants,
            posts,
            fence: Vec::new(),
            fence_triangles: 0..0,
            extent,
        }
    }

    /// The block as rows of clone segments (`vineyard.segments`, the paper's world): every
    /// segment the same `n` plants (with `plant_variation = 0`), posts at the segment ends
    /// (one where two segments meet), wires between them. `PlantSite::row` is the segment.
    fn build_segments(
        v: &VineyardConfig,
        terrain_cfg: &TerrainConfig,
        terrain: Terrain,
        world_seed: u64,
    ) -> Self {
        let (mut mesh, extent) = ground(v, terrain_cfg, &terrain, [1.0, 1.0]);

        // Posts at every segment's start and at its end unless another segment starts there.
        let ends: Vec<[Point3<f64>; 2]> = v
            .segments
            .iter()
            .map(|s| {
                let (a, b) = segment_ends(s, v.segment_length_m);
                [a, b].map(|p| Point3::new(p[0], p[1], terrain.height(p[0], p[1])))
            })
            .collect();
        let mut posts = Vec::new();
        for (i, [a, b]) in ends.iter().enumerate() {
            let shared = ends
                .iter()
                .enumerate()
                .any(|(j, e)| j != i && (e[0].xy() - b.xy()).norm() < 1.0);
            let feet: &[Point3<f64>] = if shared { &[*a] } else { &[*a, *b] };
            for foot in feet {
                shapes::post(&mut mesh, foot.cast(), 0.1, v.post_height_m as f32);
                posts.push(*foot);
            }
            for &wire in &v.wire_heights_m {
                let up = Vector3::z() * wire;
                shapes::tube(
                    &mut mesh,
                    (a + up).cast(),
                    (b + up).cast(),
                    0.0025,
                    3,
                    false,
                    Material::Wire,
                );
            }
        }

        let layout = vine_layout(v, v.segment_length_m / plants_per_segment(v) as f64);
        let n = plants_per_segment(v);
        let sites: Vec<(usize, usize)> = (0..v.segments.len())
            .flat_map(|s| (0..n).map(move |i| (s, i)))
            .collect();
        let clone_of = |i: usize| stream(world_seed, &format!("plant/clone/{i}"));
        let build = |&(s, i): &(usize, usize)| {
            let own = stream(world_seed, &format!("plant/segment/{s}/{i}"));
            vine(
                &layout,
                &mut PlantRng::new(clone_of(i), own, v.plant_variation),
            )
        };
        let local_meshes: Vec<Mesh> = if v.plant_variation == 0.0 {
            // Identical segments: build one.
            let one: Vec<Mesh> = (0..n).into_par_iter().map(|i| build(&(0, i))).collect();
            sites.iter().map(|&(_, i)| one[i].clone()).collect()
        } else {
            sites.par_iter().map(build).collect()
        };

        let mut plants = Vec::with_capacity(sites.len());
        for (&(segment, index), local) in sites.iter().zip(&local_meshes) {
            let [x0, y0, yaw_deg] = v.segments[segment];
            let (start, _) = segment_ends(&v.segments[segment], v.segment_length_m);
            let along = (index as f64 + 0.5) * layout.spacing_m;
            let yaw = yaw_deg.to_radians();
            let (x, y) = (start[0] + along * yaw.cos(), start[1] + along * yaw.sin());
            debug_assert!(((x - x0).hypot(y - y0)) <= 0.5 * v.segment_length_m);
            let base = Point3::new(x, y, terrain.height(x, y));
            let world_from_plant =
                nalgebra::Isometry3::new(base.coords.cast::<f32>(), Vector3::z() * yaw as f32);
            let start_tri = mesh.triangle_count();
            let mut placed = local.clone();
            placed
                .vertices
                .iter_mut()
                .for_each(|p| *p = world_from_plant * *p);
            mesh.append(&placed);
            plants.push(PlantSite {
                row: segment,
                index,
                base,
                triangles: start_tri..mesh.triangle_count(),
            });
        }

        Self {
            vineyard: v.clone(),
            terrain,
            mesh,
            plants,
            posts,
            fence: Vec::new(),
            fence_triangles: 0..0,
            extent,
        }
    }

    /// Vertices of plant `i` relative to its trunk foot, in the order they were built.
    pub fn plant_local_vertices(&self, i: usize) -> Vec<Point3<f32>> {
        let site = &self.plants[i];
        let base: Vector3<f32> = site.base.coords.cast();
        let mut seen = Vec::new();
        for t in site.triangles.clone() {
            for v in self.mesh.triangles[t] {
                seen.push(self.mesh.vertices[v as usize] - base);
            }
        }
        seen
    }
}

/// The ground under and around the block: fine cells over the rows and headlands, coarse
/// ones out to `margin_m` beyond; tilled soil within `soil_margin` (x, y) of the rows, grass
/// elsewhere. The mesh and the modelled extent, (min, max).
fn ground(
    v: &VineyardConfig,
    terrain_cfg: &TerrainConfig,
    terrain: &Terrain,
    soil_margin: [f64; 2],
) -> (Mesh, ([f64; 2], [f64; 2])) {
    let (lo, hi) = block_bounds(v);
    let h = v.headland_m;
    let (block_min, block_max) = ([lo[0] - h, lo[1] - h], [hi[0] + h, hi[1] + h]);
    let margin = terrain_cfg.margin_m;
    let extent = (
        [block_min[0] - margin, block_min[1] - margin],
        [block_max[0] + margin, block_max[1] + margin],
    );
    let soil = |x: f64, y: f64| {
        let inside = (lo[0] - soil_margin[0]..=hi[0] + soil_margin[0]).contains(&x)
            && (lo[1] - soil_margin[1]..=hi[1] + soil_margin[1]).contains(&y);
        if inside {
            Material::Soil
        } else {
            Material::Grass
        }
    };
    let ratio = (terrain_cfg.far_cell_m / terrain_cfg.cell_m)
        .round()
        .max(1.0) as usize;
    let mesh = terrain.mesh(
        (block_min, block_max),
        extent,
        terrain_cfg.cell_m,
        ratio,
        soil,
    );
    (mesh, extent)
}

/// Where a vine sits in its trellis: cordons on the lowest wire (at most the post height),
/// the canopy up to the post tops.
fn vine_layout(v: &VineyardConfig, spacing_m: f64) -> VineLayout {
    VineLayout {
        spacing_m,
        cordon_height_m: v
            .wire_heights_m
            .iter()
            .copied()
            .fold(f64::INFINITY, f64::min)
            .min(v.post_height_m),
        canopy_top_m: v.post_height_m,
        growth_stage: v.growth_stage,
    }
}

/// Plants in one clone segment: the segment length at about `plant_spacing_m`.
fn plants_per_segment(v: &VineyardConfig) -> usize {
    ((v.segment_length_m / v.plant_spacing_m).round() as usize).max(1)
}

/// The two ends of a segment `[x, y, yaw_deg]` of `length`: (start, end) along its axis.
fn segment_ends(s: &[f64; 3], length: f64) -> ([f64; 2], [f64; 2]) {
    let (c, yaw) = ([s[0], s[1]], s[2].to_radians());
    let half = [0.5 * length * yaw.cos(), 0.5 * length * yaw.sin()];
    (
        [c[0] - half[0], c[1] - half[1]],
        [c[0] + half[0], c[1] + half[1]],
    )
}

/// The rows' bounding box in the world frame, (min, max), headlands not included.
pub fn block_bounds(v: &VineyardConfig) -> ([f64; 2], [f64; 2]) {
    if v.segments.is_empty() {
        let last_row_y = (v.rows.max(1) - 1) as f64 * v.row_spacing_m;
        return ([0.0, 0.0], [v.row_length_m, last_row_y]);
    }
    let mut lo = [f64::INFINITY; 2];
    let mut hi = [f64::NEG_INFINITY; 2];
    for s in &v.segments {
        let (a, b) = segment_ends(s, v.segment_length_m);
        for p in [a, b] {
            for k in 0..2 {
                lo[k] = lo[k].min(p[k]);
                hi[k] = hi[k].max(p[k]);
            }
        }
    }
    (lo, hi)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn world(variation: f64) -> World {
        let v = VineyardConfig {
            rows: 2,
            plant_variation: variation,
            ..VineyardConfig::default()
        };
        World::build(&v, &TerrainConfig::default(), 7)
    }

    fn max_difference(a: &[Point3<f32>], b: &[Point3<f32>]) -> f32 {
        if a.len() != b.len() {
            return f32::INFINITY;
        }
        a.iter()
            .zip(b)
            .map(|(p, q)| (p - q).norm())
            .fold(0.0, f32::max)
    }

    #[test]
    fn variation_zero_gives_identical_plants_and_one_gives_different() {
        let clones = world(0.0);
        let first = clones.plant_local_vertices(0);
        for i in 1..clones.plants.len() {
            let d = max_difference(&first, &clones.plant_local_vertices(i));
            assert!(
                d < 1e-4,
                "plant {i} differs from plant 0 by {d} m with plant_variation = 0"
            );
        }
        let unique = world(1.0);
        let first = unique.plant_local_vertices(0);
        for i in 1..unique.plants.len() {
            let d = max_difference(&first, &unique.plant_local_vertices(i));
            assert!(
                d > 0.01,
                "plant {i} equals plant 0 (difference {d} m) with plant_variation = 1"
            );
        }
    }

    /// A map built at one growth stage is used at another (localisation across stages,
    /// issue 46) with its alignment to the world carried over, which holds only if the
    /// ground, the plants' feet, the posts and the fence stand where they stood. For both
    /// shipped worlds, with one world seed, stages 2 and 4 against stage 0: the same
    /// terrain heights, plant feet, posts, fence and extent, to the bit; the canopy's
    /// triangles differ (else the stage would change nothing).
    #[test]
    fn a_worlds_ground_rows_and_fence_are_the_same_at_every_growth_stage() {
        let root = concat!(env!("CARGO_MANIFEST_DIR"), "/../configs");
        for name in ["paper-world.toml", "world.toml"] {
            let cfg = SimConfig::from_file(&std::path::Path::new(root).join(name)).expect("loads");
            let build = |stage: f64| {
                let mut c = cfg.clone();
                c.vineyard.growth_stage = stage;
                World::from_config(&c)
            };
            let bare = build(0.0);
            let ([x0, x1], [y0, y1]) = bare.extent;
            let heights = |w: &World| -> Vec<u64> {
                (0..=40)
                    .flat_map(|i| (0..=40).map(move |j| (i, j)))
                    .map(|(i, j)| {
                        let x = x0 + (x1 - x0) * f64::from(i) / 40.0;
                        let y = y0 + (y1 - y0) * f64::from(j) / 40.0;
                        w.terrain.height(x, y).to_bits()
                    })
                    .collect()
            };
            let feet =
                |w: &World| -> Vec<Point3<f64>> { w.plants.iter().map(|p| p.base).collect() };
            for stage in [2.0, 4.0] {
                let grown = build(stage);
                assert_eq!(
                    heights(&grown),
                    heights(&bare),
                    "{name}: terrain at stage {stage}"
                );
                assert_eq!(
                    feet(&grown),
                    feet(&bare),
                    "{name}: plant feet at stage {stage}"
                );
                assert_eq!(grown.posts, bare.posts, "{name}: posts at stage {stage}");
                assert_eq!(grown.fence, bare.fence, "{name}: fence at stage {stage}");
                assert_eq!(grown.extent, bare.extent, "{name}: extent at stage {stage}");
                assert_ne!(
                    grown.mesh.triangles.len(),
                    bare.mesh.triangles.len(),
                    "{name}: stage {stage} grows no canopy"
                );
            }
        }
    }

    #[test]
    fn default_world_has_the_papers_layout() {
        let v = VineyardConfig::default();
        let w = World::build(&v, &TerrainConfig::default(), 1);
        assert_eq!(
            w.plants.len(),
            9 * 18,
            "9 rows of 18 plants one metre apart"
        );
        assert_eq!(w.posts.len(), 9 * 4, "posts every 6 m over 18 m: 4 per row");
        let tris = w.mesh.triangle_count();
        assert!(
            (50_000..600_000).contains(&tris),
            "scene has {tris} triangles"
        );
        for p in &w.plants {
            let dz = p.base.z - w.terrain.height(p.base.x, p.base.y);
            assert!(dz.abs() < 1e-9, "plant stands on the ground");
        }
    }
}
