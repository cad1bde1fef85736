//! The vineyard: terrain, trellis and vines as one triangle mesh with materials.

mod mesh;
mod shapes;
mod terrain;
mod trellis;
mod vine;

use std::ops::Range;

use nalgebra::{Point3, Vector3};
use rayon::prelude::*;

pub use mesh::{Material, Mesh};
pub use terrain::Terrain;
pub use trellis::post_xs;
pub use vine::{PlantRng, VineLayout, vine};

use crate::config::{TerrainConfig, VineyardConfig};
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
    /// Ground points of every post, row by row.
    pub posts: Vec<Point3<f64>>,
    /// Extent of the modelled ground: (min, max) in x and y.
    pub extent: ([f64; 2], [f64; 2]),
}

impl World {
    /// Builds the world deterministically from its configuration and `world_seed`.
    pub fn build(vineyard: &VineyardConfig, terrain_cfg: &TerrainConfig, world_seed: u64) -> Self {
        let terrain = Terrain::new(terrain_cfg, &mut stream(world_seed, "terrain"));
        Self::build_on(vineyard, terrain_cfg, terrain, world_seed)
    }

    /// Builds the world on a given terrain surface (tests use [`Terrain::flat`]).
    pub fn build_on(
        vineyard: &VineyardConfig,
        terrain_cfg: &TerrainConfig,
        terrain: Terrain,
        world_seed: u64,
    ) -> Self {
        let v = vineyard;
        let block_min = [-v.headland_m, -v.headland_m];
        let block_max = [
            v.row_length_m + v.headland_m,
            (v.rows.max(1) - 1) as f64 * v.row_spacing_m + v.headland_m,
        ];
        let margin = terrain_cfg.margin_m;
        let extent = (
            [block_min[0] - margin, block_min[1] - margin],
            [block_max[0] + margin, block_max[1] + margin],
        );
        // Tilled soil under the rows and lanes, grass on the headlands and beyond.
        let last_row_y = (v.rows.max(1) - 1) as f64 * v.row_spacing_m;
        let soil = |x: f64, y: f64| {
            let inside = (-0.5..=v.row_length_m + 0.5).contains(&x)
                && (-1.0..=last_row_y + 1.0).contains(&y);
            if inside {
                Material::Soil
            } else {
                Material::Grass
            }
        };
        let ratio = (terrain_cfg.far_cell_m / terrain_cfg.cell_m)
            .round()
            .max(1.0) as usize;
        let mut mesh = terrain.mesh(
            (block_min, block_max),
            extent,
            terrain_cfg.cell_m,
            ratio,
            soil,
        );

        let mut posts = Vec::new();
        for row in 0..v.rows {
            posts.extend(trellis::row_trellis(
                &mut mesh,
                v,
                &terrain,
                row as f64 * v.row_spacing_m,
            ));
        }

        let layout = VineLayout {
            spacing_m: v.plant_spacing_m,
            cordon_height_m: v
                .wire_heights_m
                .iter()
                .copied()
                .fold(f64::INFINITY, f64::min)
                .min(v.post_height_m),
            canopy_top_m: v.post_height_m,
            growth_stage: v.growth_stage,
        };
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
