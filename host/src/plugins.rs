//! Finding plugins: by explicit path, or by name on the search path (the config's
//! `plugin_dirs`, then `VINEBENCH_PLUGIN_PATH`, then the directory of the `vinebench`
//! executable, where `cargo build` puts the workspace's plugins).

use std::path::{Path, PathBuf};

use anyhow::{Context as _, bail};

/// The directories searched for plugins, in order.
pub fn search_path(config_dirs: &[PathBuf]) -> Vec<PathBuf> {
    let mut dirs: Vec<PathBuf> = config_dirs.to_vec();
    if let Some(env) = std::env::var_os("VINEBENCH_PLUGIN_PATH") {
        dirs.extend(std::env::split_paths(&env));
    }
    if let Some(exe_dir) = std::env::current_exe()
        .ok()
        .and_then(|p| p.parent().map(Path::to_owned))
    {
        dirs.push(exe_dir);
    }
    dirs
}

/// The library file a plugin called `name` is expected in (`wheel-odometry` →
/// `libwheel_odometry.so` on Linux): cargo's naming of a cdylib crate.
pub fn file_name(name: &str) -> String {
    format!(
        "{}{}{}",
        std::env::consts::DLL_PREFIX,
        name.replace('-', "_"),
        std::env::consts::DLL_SUFFIX
    )
}

/// Resolves a plugin given by name or path. A value containing a path separator or ending
/// in the library suffix is a path.
pub fn resolve(name_or_path: &str, dirs: &[PathBuf]) -> anyhow::Result<PathBuf> {
    let looks_like_path = name_or_path.contains(std::path::MAIN_SEPARATOR)
        || name_or_path.ends_with(std::env::consts::DLL_SUFFIX);
    if looks_like_path {
        let p = PathBuf::from(name_or_path);
        if !p.is_file() {
            bail!("plugin '{name_or_path}': no such file");
        }
        return p.canonicalize().with_context(|| name_or_path.to_owned());
    }
    let file = file_name(name_or_path);
    for dir in dirs {
        let candidate = dir.join(&file);
        if candidate.is_file() {
            return candidate
                .canonicalize()
                .with_context(|| candidate.display().to_string());
        }
    }
    let searched: Vec<String> = dirs.iter().map(|d| d.display().to_string()).collect();
    bail!(
        "plugin '{name_or_path}' not found: no {file} in {}",
        searched.join(", ")
    )
}

/// Every library file in the search path that may be a plugin.
pub fn candidates(dirs: &[PathBuf]) -> Vec<PathBuf> {
    let mut found = Vec::new();
    for dir in dirs {
        let Ok(entries) = std::fs::read_dir(dir) else {
            continue;
        };
        let mut files: Vec<PathBuf> = entries
            .filter_map(Result::ok)
            .map(|e| e.path())
            .filter(|p| {
                let name = p
                    .file_name()
                    .map(|n| n.to_string_lossy().into_owned())
                    .unwrap_or_default();
                name.starts_with(std::env::consts::DLL_PREFIX)
                    && name.ends_with(std::env::consts::DLL_SUFFIX)
            })
            .collect();
        files.sort();
        found.extend(files);
    }
    found
}
