//! `map.bin`: a map a plugin saved at `finish` (`plugin_api::SavedMap`), kept in its run
//! folder to localise in later (`vinebench localize --map RUN_DIR`).
//!
//! The plugin's bytes are opaque to the host; the file wraps them in a head that says whose
//! they are, so that a map handed to another plugin, a truncated copy or a flipped bit is
//! one line naming the file and the plugin, never bytes a plugin chokes on:
//!
//! ```text
//! "VBMAP1\n"                 7 bytes, the file's magic and layout version
//! head length                u32, little-endian
//! head                       TOML: plugin, plugin_version, format, format_version,
//!                            bytes (payload length), sha256 (hex digest of the payload)
//! payload                    the plugin's bytes
//! ```

use std::path::Path;

use plugin_api::SavedMap;
use serde::{Deserialize, Serialize};
use sha2::Digest as _;

/// The first bytes of every `map.bin`.
pub const MAP_MAGIC: &[u8; 7] = b"VBMAP1\n";

/// What a `map.bin` says of its payload.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MapHead {
    /// The plugin that saved it (its `NAME`): only it can read the payload.
    pub plugin: String,
    pub plugin_version: String,
    /// The plugin's name and version of the payload's format.
    pub format: String,
    pub format_version: u32,
    /// The payload's length and SHA-256 (hex).
    pub bytes: u64,
    pub sha256: String,
}

/// Why a `map.bin` cannot be used: one line naming the file (and the plugin).
#[derive(Debug, thiserror::Error)]
pub enum MapFileError {
    #[error("{path}: {source}")]
    Io {
        path: String,
        source: std::io::Error,
    },
    #[error("{path}: not a vinebench map (it does not start with VBMAP1)")]
    NotAMap { path: String },
    #[error("{path}: corrupt map: {why}")]
    Corrupt { path: String, why: String },
    #[error("{path}: a map saved by plugin {saved_by}, not by {plugin}; localise with {saved_by}")]
    Foreign {
        path: String,
        saved_by: String,
        plugin: String,
    },
}

/// The error's line, naming `plugin` where it does not already.
pub fn with_plugin(e: MapFileError, plugin: &str) -> String {
    match e {
        e @ MapFileError::Foreign { .. } => e.to_string(),
        e => format!("{e} (localising with plugin {plugin})"),
    }
}

fn sha256_hex(bytes: &[u8]) -> String {
    sha2::Sha256::digest(bytes)
        .iter()
        .map(|b| format!("{b:02x}"))
        .collect()
}

/// The file's bytes for `map`, saved by `plugin` of `plugin_version`.
pub fn encode_map(plugin: &str, plugin_version: &str, map: &SavedMap) -> Vec<u8> {
    let head = MapHead {
        plugin: plugin.to_owned(),
        plugin_version: plugin_version.to_owned(),
        format: map.format.clone(),
        format_version: map.version,
        bytes: map.bytes.len() as u64,
        sha256: sha256_hex(&map.bytes),
    };
    let head = toml::to_string(&head).expect("a map head serialises");
    let mut out = Vec::with_capacity(MAP_MAGIC.len() + 4 + head.len() + map.bytes.len());
    out.extend_from_slice(MAP_MAGIC);
    out.extend_from_slice(&(head.len() as u32).to_le_bytes());
    out.extend_from_slice(head.as_bytes());
    out.extend_from_slice(&map.bytes);
    out
}

/// Writes `map` as `path` (whole or not at all: a temporary file renamed).
pub fn write_map(
    path: &Path,
    plugin: &str,
    plugin_version: &str,
    map: &SavedMap,
) -> anyhow::Result<()> {
    super::write_atomic(path, &encode_map(plugin, plugin_version, map))
}

/// The head and payload of the `map.bin` at `path`, checked whole: its magic, its head, the
/// payload's length and digest, and that `plugin` saved it (any plugin: `None`).
pub fn read_map(path: &Path, plugin: Option<&str>) -> Result<(MapHead, Vec<u8>), MapFileError> {
    let name = path.display().to_string();
    let bytes = std::fs::read(path).map_err(|source| MapFileError::Io {
        path: name.clone(),
        source,
    })?;
    decode_map(&bytes, &name, plugin)
}

/// [`read_map`] of bytes already read; `name` names them in errors.
pub fn decode_map(
    bytes: &[u8],
    name: &str,
    plugin: Option<&str>,
) -> Result<(MapHead, Vec<u8>), MapFileError> {
    let corrupt = |why: String| MapFileError::Corrupt {
        path: name.to_owned(),
        why,
    };
    let Some(rest) = bytes.strip_prefix(MAP_MAGIC.as_slice()) else {
        return Err(MapFileError::NotAMap {
            path: name.to_owned(),
        });
    };
    if rest.len() < 4 {
        return Err(corrupt("it ends inside its head's length".into()));
    }
    let head_len = u32::from_le_bytes(rest[..4].try_into().expect("4 bytes")) as usize;
    let rest = &rest[4..];
    if rest.len() < head_len {
        return Err(corrupt(format!(
            "its head of {head_len} bytes is cut short ({} left)",
            rest.len()
        )));
    }
    let head_text = std::str::from_utf8(&rest[..head_len])
        .map_err(|_| corrupt("its head is not UTF-8".into()))?;
    let head: MapHead = toml::from_str(head_text)
        .map_err(|e| corrupt(format!("unreadable head: {}", e.message().trim())))?;
    let payload = &rest[head_len..];
    if let Some(plugin) = plugin
        && head.plugin != plugin
    {
        return Err(MapFileError::Foreign {
            path: name.to_owned(),
            saved_by: head.plugin,
            plugin: plugin.to_owned(),
        });
    }
    if payload.len() as u64 != head.bytes {
        return Err(corrupt(format!(
            "its head says {} bytes of map, the file holds {}",
            head.bytes,
            payload.len()
        )));
    }
    if sha256_hex(payload) != head.sha256 {
        return Err(corrupt(
            "its bytes do not match their SHA-256 (changed since the plugin saved it)".into(),
        ));
    }
    Ok((head, payload.to_vec()))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn saved() -> SavedMap {
        SavedMap {
            format: "keyframes".into(),
            version: 3,
            bytes: (0..=255u8).collect(),
        }
    }

    #[test]
    fn a_map_reads_back_and_every_damage_is_one_line_naming_file_and_plugin() {
        let bytes = encode_map("rtabmap", "0.1.0", &saved());
        let (head, payload) =
            decode_map(&bytes, "run/map.bin", Some("rtabmap")).expect("reads back");
        assert_eq!(payload, saved().bytes);
        assert_eq!(
            (head.format.as_str(), head.format_version, head.bytes),
            ("keyframes", 3, 256)
        );

        let one_line = |e: MapFileError| {
            let text = e.to_string();
            assert!(!text.contains('\n'), "{text}");
            assert!(text.starts_with("run/map.bin: "), "{text}");
            text
        };
        let foreign =
            one_line(decode_map(&bytes, "run/map.bin", Some("orbslam2")).expect_err("foreign"));
        assert!(
            foreign.contains("plugin rtabmap, not by orbslam2"),
            "{foreign}"
        );
        let mut flipped = bytes.clone();
        *flipped.last_mut().expect("bytes") ^= 1;
        let text =
            one_line(decode_map(&flipped, "run/map.bin", Some("rtabmap")).expect_err("flipped"));
        assert!(text.contains("SHA-256"), "{text}");
        let text = one_line(
            decode_map(&bytes[..bytes.len() - 1], "run/map.bin", Some("rtabmap")).expect_err("cut"),
        );
        assert!(
            text.contains("says 256 bytes of map, the file holds 255"),
            "{text}"
        );
        let text =
            one_line(decode_map(b"P5\n10 10\n", "run/map.bin", Some("rtabmap")).expect_err("pgm"));
        assert!(text.contains("not a vinebench map"), "{text}");
        let text =
            one_line(decode_map(&bytes[..20], "run/map.bin", Some("rtabmap")).expect_err("head"));
        assert!(text.contains("cut short"), "{text}");
    }
}
