//! Writers for a plugin's map outputs: point clouds as binary PLY (and their reader),
//! occupancy grids in the ROS map_server format (PGM + YAML).

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

/// The points of a PLY file as [`write_ply`] writes it: binary little-endian, one `vertex`
/// element of `float` x, y, z and nothing else (PLY format, Turk 1994, as written by
/// `write_ply`; any other layout is an error naming the file).
pub fn read_ply(path: &Path) -> anyhow::Result<Vec<[f32; 3]>> {
    let bytes = std::fs::read(path).with_context(|| path.display().to_string())?;
    parse_ply(&bytes).with_context(|| path.display().to_string())
}

fn parse_ply(bytes: &[u8]) -> anyhow::Result<Vec<[f32; 3]>> {
    const END: &[u8] = b"end_header\n";
    let end = bytes
        .windows(END.len())
        .position(|w| w == END)
        .context("no end_header line")?
        + END.len();
    let header = std::str::from_utf8(&bytes[..end]).context("the PLY header is not text")?;
    let lines: Vec<&str> = header.lines().collect();
    let count = match lines.as_slice() {
        [
            "ply",
            "format binary_little_endian 1.0",
            vertex,
            "property float x",
            "property float y",
            "property float z",
            "end_header",
        ] => vertex
            .strip_prefix("element vertex ")
            .and_then(|n| n.parse::<usize>().ok()),
        _ => None,
    }
    .with_context(|| {
        format!("PLY header {header:?}: expected binary little-endian vertices of float x, y, z")
    })?;
    let body = &bytes[end..];
    let need = count
        .checked_mul(12)
        .with_context(|| format!("{count} vertices: more bytes than any file holds"))?;
    anyhow::ensure!(
        body.len() == need,
        "{count} vertices need {need} bytes after the header, found {}",
        body.len()
    );
    Ok(body
        .chunks_exact(12)
        .map(|c| [0, 4, 8].map(|i| f32::from_le_bytes(c[i..i + 4].try_into().expect("4 bytes"))))
        .collect())
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_written_ply_reads_back_and_a_damaged_one_names_the_file() {
        let dir = tempfile::tempdir().expect("temp dir");
        let path = dir.path().join("map.ply");
        let points = [[1.0, -2.5, 3.25], [f32::MIN_POSITIVE, 0.0, -0.0]];
        write_ply(&path, &points).expect("write");
        let back = read_ply(&path).expect("read");
        assert_eq!(
            back.iter()
                .flatten()
                .map(|v| v.to_bits())
                .collect::<Vec<_>>(),
            points
                .iter()
                .flatten()
                .map(|v| v.to_bits())
                .collect::<Vec<_>>()
        );
        let bytes = std::fs::read(&path).expect("bytes");
        std::fs::write(&path, &bytes[..bytes.len() - 1]).expect("cut");
        let err = format!("{:#}", read_ply(&path).expect_err("a cut file"));
        assert!(
            err.contains("map.ply") && err.contains("2 vertices need 24 bytes"),
            "{err}"
        );
    }

    /// fuzz/regressions/ply/vertex-count-overflow.ply: a vertex count whose byte size
    /// overflowed `usize` (a panic in debug builds, a wrong size check in release ones).
    #[test]
    fn a_vertex_count_past_the_address_space_is_refused() {
        let header = "ply\nformat binary_little_endian 1.0\nelement vertex 1537228672809129302\n\
                      property float x\nproperty float y\nproperty float z\nend_header\n";
        let err = format!("{:#}", parse_ply(header.as_bytes()).expect_err("too many"));
        assert!(err.contains("1537228672809129302 vertices"), "{err}");
    }
}
