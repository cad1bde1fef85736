//! Writers for a plugin's map outputs: point clouds as binary PLY, occupancy grids in the
//! ROS map_server format (PGM + YAML).

use std::io::Write;
use std::path::Path;

use anyhow::Context as _;
use plugin_api::OccupancyGrid;

/// Binary little-endian PLY of `points` (x, y, z as float).
pub fn write_ply(path: &Path, points: &[[f32; 3]]) -> anyhow::Result<()> {
    let mut bytes = format!(
        "ply\nformat binary_little_endian 1.0\nelement vertex {}\nproperty float x\nproperty float y\nproperty float z\nend_header\n",
        points.len()
    )
    .into_bytes();
    for p in points {
        for v in p {
            bytes.extend_from_slice(&v.to_le_bytes());
        }
    }
    std::fs::write(path, bytes).with_context(|| path.display().to_string())
}

/// map_server's trinary image: occupied black (0), free white (254), unknown grey (205),
/// rows from the top, so the grid's last row comes first.
pub fn write_grid(pgm: &Path, yaml: &Path, grid: &OccupancyGrid) -> anyhow::Result<()> {
    anyhow::ensure!(
        grid.cells.len() == grid.width as usize * grid.height as usize,
        "occupancy grid has {} cells for {} x {}",
        grid.cells.len(),
        grid.width,
        grid.height
    );
    let mut bytes = format!("P5\n{} {}\n255\n", grid.width, grid.height).into_bytes();
    for row in (0..grid.height as usize).rev() {
        let start = row * grid.width as usize;
        bytes.extend(
            grid.cells[start..start + grid.width as usize]
                .iter()
                .map(|&c| match c {
                    c if c < 0 => 205u8,
                    c if c >= 65 => 0,
                    c if c <= 25 => 254,
                    _ => 205,
                }),
        );
    }
    std::fs::write(pgm, bytes).with_context(|| pgm.display().to_string())?;
    let image = pgm
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default();
    let mut f = std::fs::File::create(yaml).with_context(|| yaml.display().to_string())?;
    writeln!(
        f,
        "image: {image}\nresolution: {}\norigin: [{}, {}, {}]\nnegate: 0\noccupied_thresh: 0.65\nfree_thresh: 0.25",
        grid.resolution_m, grid.origin[0], grid.origin[1], grid.origin[2]
    )?;
    Ok(())
}
