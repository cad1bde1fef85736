//! A top view of the world with the route: the first picture a user looks at. Ground
//! shaded by material and height, canopy footprints, posts, the planned route and the
//! driven ground-truth path.

use std::path::Path;

use eval::plot::{Chart, Mark, Rgb, Swatch};
use sim::Simulation;
use sim::world::Material;

const PX_PER_M: f64 = 20.0;
const CELL_M: f64 = 0.25;
const LEAF: Rgb = [60, 120, 45];
const GRAPE: Rgb = [90, 40, 110];
const STEM: Rgb = [90, 60, 40];
const POST: Rgb = [70, 70, 70];
const FENCE: Rgb = [120, 80, 40];
const PLANNED: Rgb = [255, 255, 255];
const DRIVEN: Rgb = [220, 30, 30];
const START: Rgb = [30, 200, 60];
const END: Rgb = [20, 20, 20];

fn shade(color: Rgb, factor: f64) -> Rgb {
    color.map(|c| (f64::from(c) * factor).clamp(0.0, 255.0) as u8)
}

/// Draws the top view of `sim`'s world and route to a PNG at `path`.
pub fn draw(sim: &Simulation, path: &Path) -> anyhow::Result<()> {
    let v = &sim.world.vineyard;
    let pad = v.headland_m + 1.0;
    let (lo, hi) = sim::world::block_bounds(v);
    let (mut min, mut max) = ((lo[0] - pad, lo[1] - pad), (hi[0] + pad, hi[1] + pad));
    // The fence, where there is one, and its surroundings.
    for f in &sim.world.fence {
        min = (min.0.min(f.x - 1.5), min.1.min(f.y - 1.5));
        max = (max.0.max(f.x + 1.5), max.1.max(f.y + 1.5));
    }
    let title = if v.segments.is_empty() {
        format!("{} rows x {} m", v.rows, v.row_length_m)
    } else {
        format!(
            "{} clone segments of {} m",
            v.segments.len(),
            v.segment_length_m
        )
    };
    let mut chart = Chart::top_view(format!(
        "{title}, growth stage {}: route and driven path",
        v.growth_stage
    ));
    chart.x_range = Some((min.0, max.0));
    chart.y_range = Some((min.1, max.1));
    let mut ground = Vec::new();

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
            let in_block = (lo[0] - 0.5..=hi[0] + 0.5).contains(&cx)
                && (lo[1] - 1.0..=hi[1] + 1.0).contains(&cy);
            let base: Rgb = if in_block {
                [150, 120, 90]
            } else {
                [120, 165, 95]
            };
            let h = terrain.height(cx, cy) / amplitude;
            ground.push((
                [(x, y), (x + CELL_M, y + CELL_M)],
                shade(base, 1.0 + 0.25 * h),
            ));
        }
    }
    chart.marks.push(Mark::Rects { rects: ground });

    // Canopy: the footprint of each plant's leaves, wood where there are none.
    let mesh = &sim.world.mesh;
    let (mut leaves, mut grapes, mut stems) = (Vec::new(), Vec::new(), Vec::new());
    for plant in &sim.world.plants {
        for t in plant.triangles.clone() {
            let points = match mesh.materials[t] {
                Material::Leaf => &mut leaves,
                Material::Grape => &mut grapes,
                _ => continue,
            };
            let [a, b, c] = mesh.corners(t);
            let centre = (a + b.coords + c.coords) / 3.0;
            points.push((f64::from(centre.x), f64::from(centre.y)));
        }
        stems.push((plant.base.x, plant.base.y));
    }
    for (points, color, radius_px) in [(leaves, LEAF, 1), (grapes, GRAPE, 1), (stems, STEM, 2)] {
        chart.marks.push(Mark::Dots {
            points,
            color,
            radius_px,
        });
    }
    chart.marks.push(Mark::Rects {
        rects: sim
            .world
            .posts
            .iter()
            .map(|post| {
                (
                    [
                        (post.x - 0.06, post.y - 0.06),
                        (post.x + 0.06, post.y + 0.06),
                    ],
                    POST,
                )
            })
            .collect(),
    });

    // Fence panels as thick lines along their length.
    let [length, ..] = sim.config.fence.panel_size_m;
    for &[x, y, yaw_deg] in &sim.config.fence.panels {
        let (dx, dy) = (
            0.5 * length * yaw_deg.to_radians().cos(),
            0.5 * length * yaw_deg.to_radians().sin(),
        );
        chart.marks.push(Mark::Line {
            points: vec![(x - dx, y - dy), (x + dx, y + dy)],
            color: FENCE,
            width_px: 3,
        });
    }

    // Route as planned (thin) and as driven (thick), start and end marked.
    for leg in &sim.route.legs {
        if let sim::robot::Leg::Drive(points) = leg {
            let line: Vec<(f64, f64)> = points.iter().map(|p| (p.x, p.y)).collect();
            chart.marks.push(Mark::Line {
                points: line,
                color: PLANNED,
                width_px: 1,
            });
        }
    }
    let step = 50_000_000;
    let driven: Vec<(f64, f64)> = (0..=sim.duration_ns() / step)
        .map(|k| {
            let p = sim.trajectory.nominal_pose(k * step).translation.vector;
            (p.x, p.y)
        })
        .collect();
    if let (Some(&start), Some(&end)) = (driven.first(), driven.last()) {
        chart.marks.push(Mark::Line {
            points: driven,
            color: DRIVEN,
            width_px: 3,
        });
        chart.marks.push(Mark::Dots {
            points: vec![start],
            color: START,
            radius_px: 7,
        });
        chart.marks.push(Mark::Dots {
            points: vec![end],
            color: END,
            radius_px: 5,
        });
    }
    let line = |color| Swatch::Line { color, width_px: 3 };
    chart.legend = vec![
        (line(DRIVEN), "driven (ground truth)".into()),
        (line(PLANNED), "planned route".into()),
        (Swatch::Box(START), "start".into()),
        (Swatch::Box(END), "end".into()),
        (Swatch::Box(LEAF), "leaves".into()),
        (Swatch::Box(GRAPE), "grapes".into()),
        (Swatch::Box(POST), "posts".into()),
    ];
    if !sim.config.fence.panels.is_empty() {
        chart.legend.push((line(FENCE), "fence".into()));
    }
    let width = ((max.0 - min.0) * PX_PER_M).round() as u32 + 100;
    chart.save(path, width)?;
    Ok(())
}
