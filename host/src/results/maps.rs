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
/// rows from the top, so the grid's last row comes first; the YAML's thresholds are
/// map_saver's (`occupied_thresh: 0.65`, `free_thresh: 0.196`), under which map_server reads
/// the three greys back as they were written (205 is p = 0.196 08, just above the free
/// threshold: unknown).
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
        "image: {image}\nresolution: {}\norigin: [{}, {}, {}]\nnegate: 0\noccupied_thresh: 0.65\nfree_thresh: 0.196",
        grid.resolution_m, grid.origin[0], grid.origin[1], grid.origin[2]
    )?;
    Ok(())
}

/// A map_server map: the `grid.yaml` at `yaml` and the image it names (binary PGM, P5),
/// read as map_server's trinary mode does: occupancy `p = (255 - value) / 255` (`negate: 1`
/// flips it), occupied (100) above `occupied_thresh`, free (0) below `free_thresh`, unknown
/// (-1) between; the image's first row is the grid's last.
pub fn read_grid(yaml: &Path) -> anyhow::Result<OccupancyGrid> {
    let name = yaml.display();
    let text = std::fs::read_to_string(yaml).with_context(|| name.to_string())?;
    let mut image = None;
    let mut resolution = None;
    let mut origin = None;
    let (mut negate, mut occupied, mut free) = (false, 0.65, 0.196);
    for line in text.lines() {
        let Some((key, value)) = line.split_once(':') else {
            continue;
        };
        let value = value.trim();
        let number = |v: &str| -> anyhow::Result<f64> {
            v.trim()
                .parse::<f64>()
                .with_context(|| format!("{name}: {} is not a number: {v:?}", key.trim()))
        };
        match key.trim() {
            "image" => image = Some(value.trim_matches(['"', '\'']).to_owned()),
            "resolution" => resolution = Some(number(value)?),
            "origin" => {
                let inner = value.trim_start_matches('[').trim_end_matches(']');
                let v: Vec<f64> = inner.split(',').map(number).collect::<Result<_, _>>()?;
                anyhow::ensure!(v.len() == 3, "{name}: origin is [x, y, yaw], got {value}");
                origin = Some([v[0], v[1], v[2]]);
            }
            "negate" => negate = number(value)? != 0.0,
            "occupied_thresh" => occupied = number(value)?,
            "free_thresh" => free = number(value)?,
            _ => {}
        }
    }
    let (Some(image), Some(resolution_m), Some(origin)) = (image, resolution, origin) else {
        anyhow::bail!("{name}: a map_server map needs image, resolution and origin");
    };
    anyhow::ensure!(
        resolution_m.is_finite() && resolution_m > 0.0 && origin.iter().all(|v| v.is_finite()),
        "{name}: resolution must be positive and origin finite"
    );
    let pgm = yaml.parent().unwrap_or(Path::new(".")).join(&image);
    let bytes = std::fs::read(&pgm).with_context(|| pgm.display().to_string())?;
    let (width, height, pixels) =
        parse_pgm(&bytes).map_err(|why| anyhow::anyhow!("{}: {why}", pgm.display()))?;
    let mut cells = Vec::with_capacity(pixels.len());
    for row in (0..height).rev() {
        for &v in &pixels[row * width..(row + 1) * width] {
            let mut p = (255.0 - f64::from(v)) / 255.0;
            if negate {
                p = 1.0 - p;
            }
            cells.push(if p > occupied {
                100
            } else if p < free {
                0
            } else {
                -1
            });
        }
    }
    Ok(OccupancyGrid {
        resolution_m,
        origin,
        width: width as u32,
        height: height as u32,
        cells,
    })
}

/// Width, height and pixels of a binary 8-bit PGM (P5, maxval 255, `#` comments).
fn parse_pgm(bytes: &[u8]) -> Result<(usize, usize, &[u8]), String> {
    let mut at = 0;
    let mut token = || -> Result<&[u8], String> {
        loop {
            while at < bytes.len() && bytes[at].is_ascii_whitespace() {
                at += 1;
            }
            if at < bytes.len() && bytes[at] == b'#' {
                while at < bytes.len() && bytes[at] != b'\n' {
                    at += 1;
                }
                continue;
            }
            break;
        }
        let start = at;
        while at < bytes.len() && !bytes[at].is_ascii_whitespace() {
            at += 1;
        }
        (start < at)
            .then(|| &bytes[start..at])
            .ok_or_else(|| "the PGM header ends early".to_owned())
    };
    if token()? != b"P5" {
        return Err("not a binary PGM (P5)".into());
    }
    let mut number = || -> Result<usize, String> {
        std::str::from_utf8(token()?)
            .ok()
            .and_then(|t| t.parse().ok())
            .ok_or_else(|| "a PGM header field is not a number".to_owned())
    };
    let (width, height, maxval) = (number()?, number()?, number()?);
    if maxval != 255 {
        return Err(format!("maxval {maxval}: only 8-bit PGM (255) is read"));
    }
    let body = &bytes[(at + 1).min(bytes.len())..];
    let n = width
        .checked_mul(height)
        .ok_or_else(|| "impossibly large".to_owned())?;
    if body.len() != n {
        return Err(format!(
            "{width} x {height} pixels, but {} bytes of pixels",
            body.len()
        ));
    }
    Ok((width, height, body))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A grid written as map_server's trinary image reads back cell for cell.
    #[test]
    fn a_written_grid_reads_back() {
        let dir = tempfile::tempdir().expect("temp dir");
        let grid = OccupancyGrid {
            resolution_m: 0.05,
            origin: [-3.5, 2.25, 0.0],
            width: 3,
            height: 2,
            cells: vec![0, 100, -1, 100, 0, 0],
        };
        let (pgm, yaml) = (dir.path().join("grid.pgm"), dir.path().join("grid.yaml"));
        write_grid(&pgm, &yaml, &grid).expect("write");
        assert_eq!(read_grid(&yaml).expect("read"), grid);
        std::fs::write(&pgm, b"P5\n3 2\n255\n\x00").expect("write");
        let e = read_grid(&yaml).expect_err("short").to_string();
        assert!(e.contains("grid.pgm: 3 x 2 pixels, but 1 bytes"), "{e}");
    }

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
