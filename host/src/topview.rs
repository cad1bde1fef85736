//! A top view of the world with the route: the first picture a user looks at. Ground
//! shaded by material and height, canopy footprints, posts, the planned route and the
//! driven ground-truth path.

use std::path::Path;

use eval::plot::{Bounds, Canvas, Rgb};
use sim::Simulation;
use sim::world::Material;

const PX_PER_M: f64 = 20.0;
const CELL_M: f64 = 0.25;

fn shade(color: Rgb, factor: f64) -> Rgb {
    color.map(|c| (f64::from(c) * factor).clamp(0.0, 255.0) as u8)
}

/// Draws the top view of `sim`'s world and route to a PNG at `path`.
pub fn draw(sim: &Simulation, path: &Path) -> anyhow::Result<()> {
    let v = &sim.world.vineyard;
    let pad = v.headland_m + 1.0;
    let last_row = (v.rows.max(1) - 1) as f64 * v.row_spacing_m;
    let (min, max) = ((-pad, -pad), (v.row_length_m + pad, last_row + pad));
    let size = |extent: f64| (extent * PX_PER_M).round() as u32;
    let mut canvas = Canvas::new(
        size(max.0 - min.0),
        size(max.1 - min.1),
        Bounds::new(min, max),
    );

    // Ground: soil in the block, grass around it, brighter where higher.
    let terrain = &sim.world.terrain;
    let amplitude =
        (sim.config.terrain.amplitude_m + sim.config.terrain.bump_amplitude_m).max(1e-3);
    let (nx, ny) = (
        ((max.0 - min.0) / CELL_M) as usize,
        ((max.1 - min.1) / CELL_M) as usize,
    );
    for j in 0..ny {
        for i in 0..nx {
            let (x, y) = (min.0 + i as f64 * CELL_M, min.1 + j as f64 * CELL_M);
            let (cx, cy) = (x + 0.5 * CELL_M, y + 0.5 * CELL_M);
            let in_block = (-0.5..=v.row_length_m + 0.5).contains(&cx)
                && (-1.0..=last_row + 1.0).contains(&cy);
            let base: Rgb = if in_block {
                [150, 120, 90]
            } else {
                [120, 165, 95]
            };
            let h = terrain.height(cx, cy) / amplitude;
            canvas.fill_rect(
                (x, y),
                (x + CELL_M, y + CELL_M),
                shade(base, 1.0 + 0.25 * h),
            );
        }
    }

    // Canopy: the footprint of each plant's leaves, wood where there are none.
    let mesh = &sim.world.mesh;
    for plant in &sim.world.plants {
        for t in plant.triangles.clone() {
            let color: Rgb = match mesh.materials[t] {
                Material::Leaf => [60, 120, 45],
                Material::Grape => [90, 40, 110],
                _ => continue,
            };
            let [a, b, c] = mesh.corners(t);
            let centre = (a + b.coords + c.coords) / 3.0;
            canvas.circle((f64::from(centre.x), f64::from(centre.y)), 1.5, color);
        }
        canvas.circle((plant.base.x, plant.base.y), 2.0, [90, 60, 40]);
    }
    for post in &sim.world.posts {
        canvas.fill_rect(
            (post.x - 0.06, post.y - 0.06),
            (post.x + 0.06, post.y + 0.06),
            [70, 70, 70],
        );
    }

    // Route as planned (thin) and as driven (thick), start and end marked.
    for leg in &sim.route.legs {
        if let sim::robot::Leg::Drive(points) = leg {
            let line: Vec<(f64, f64)> = points.iter().map(|p| (p.x, p.y)).collect();
            canvas.polyline(&line, [255, 255, 255], 1.0);
        }
    }
    let step = 50_000_000;
    let driven: Vec<(f64, f64)> = (0..=sim.duration_ns() / step)
        .map(|k| {
            let p = sim.trajectory.pose(k * step).translation.vector;
            (p.x, p.y)
        })
        .collect();
    canvas.polyline(&driven, [220, 30, 30], 3.0);
    if let (Some(&start), Some(&end)) = (driven.first(), driven.last()) {
        canvas.circle(start, 7.0, [30, 200, 60]);
        canvas.circle(end, 5.0, [20, 20, 20]);
    }
    canvas.save_png(path)?;
    Ok(())
}
