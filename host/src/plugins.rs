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
/// in the library suffix is a path. A name must be the plugin's own, exactly: `lio_sam` finds
/// the library of `lio-sam` (cargo names both files alike) but is refused with a "did you
/// mean", as is a name with no library, by the closest names on the search path.
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
            let path = candidate
                .canonicalize()
                .with_context(|| candidate.display().to_string())?;
            // The library's own name, asked in a child process (no plugin is loaded into
            // the supervisor). A library that does not load fails its runs with the reason.
            if let Ok(declared) = describe(&path)
                && declared.name != name_or_path
            {
                bail!(
                    "plugin '{name_or_path}' not found: did you mean '{}'? ({} is the plugin '{}')",
                    declared.name,
                    path.display(),
                    declared.name
                );
            }
            return Ok(path);
        }
    }
    let searched: Vec<String> = dirs.iter().map(|d| d.display().to_string()).collect();
    let names: Vec<String> = candidates(dirs)
        .iter()
        .filter_map(|p| name_of_file(p))
        .collect();
    let hint = closest(name_or_path, &names)
        .map(|n| format!("; did you mean '{n}'?"))
        .unwrap_or_default();
    bail!(
        "plugin '{name_or_path}' not found: no {file} in {}{hint}",
        searched.join(", ")
    )
}

/// What a plugin library says it is.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Declared {
    pub name: String,
    pub version: String,
    /// `Rust` or `C`.
    pub door: String,
}

/// The name, version and door of the plugin library at `path`, read in a child process
/// (`vinebench worker --describe`); `Err` is why it does not load.
pub fn describe(path: &Path) -> anyhow::Result<Declared> {
    let exe = std::env::current_exe().context("cannot find the vinebench executable")?;
    let output = std::process::Command::new(exe)
        .arg("worker")
        .arg("--describe")
        .arg(path)
        .stdin(std::process::Stdio::null())
        .output()
        .context("cannot start a process to load the plugin")?;
    let text = String::from_utf8_lossy(&output.stdout);
    let mut fields = text.trim_end().split('\t');
    match (
        output.status.success(),
        fields.next(),
        fields.next(),
        fields.next(),
    ) {
        (true, Some(name), Some(version), Some(door)) => Ok(Declared {
            name: name.to_owned(),
            version: version.to_owned(),
            door: door.to_owned(),
        }),
        _ => {
            let stderr = String::from_utf8_lossy(&output.stderr);
            let why = stderr
                .lines()
                .rev()
                .find_map(|l| l.strip_prefix("error: "))
                .map(str::to_owned)
                .unwrap_or_else(|| describe_status(output.status));
            bail!("{why}")
        }
    }
}

/// How a describing child ended without an answer.
fn describe_status(status: std::process::ExitStatus) -> String {
    use std::os::unix::process::ExitStatusExt as _;
    match status.signal() {
        Some(sig) => format!("loading it killed the process (signal {sig})"),
        None => format!("loading it failed (status {})", status.code().unwrap_or(-1)),
    }
}

/// The plugin name cargo's file naming suggests for a library (`libwheel_odometry.so` →
/// `wheel-odometry`), for suggestions only: the library's own name is what counts.
fn name_of_file(path: &Path) -> Option<String> {
    let name = path.file_name()?.to_str()?;
    let stem = name
        .strip_prefix(std::env::consts::DLL_PREFIX)?
        .strip_suffix(std::env::consts::DLL_SUFFIX)?;
    Some(stem.replace('_', "-"))
}

/// The name among `names` closest to `wanted` by edit distance, if close enough to be a
/// typo (at most a third of its length, and 3).
fn closest<'a>(wanted: &str, names: &'a [String]) -> Option<&'a str> {
    let limit = (wanted.chars().count() / 3).clamp(1, 3);
    names
        .iter()
        .map(|n| (levenshtein(wanted, n), n))
        .filter(|(d, _)| *d <= limit)
        .min()
        .map(|(_, n)| n.as_str())
}

/// Edit distance (insertions, deletions, substitutions) between two strings, by characters.
fn levenshtein(a: &str, b: &str) -> usize {
    let b: Vec<char> = b.chars().collect();
    let mut row: Vec<usize> = (0..=b.len()).collect();
    for (i, ca) in a.chars().enumerate() {
        let mut diagonal = row[0];
        row[0] = i + 1;
        for (j, cb) in b.iter().enumerate() {
            let above = row[j + 1];
            row[j + 1] = (above + 1)
                .min(row[j] + 1)
                .min(diagonal + usize::from(ca != *cb));
            diagonal = above;
        }
    }
    row[b.len()]
}

/// The folder a file's relative paths are relative to: its own, absolute.
pub fn folder_of(file: &Path) -> anyhow::Result<PathBuf> {
    match file.parent() {
        Some(dir) if !dir.as_os_str().is_empty() => std::path::absolute(dir),
        _ => std::env::current_dir(),
    }
    .with_context(|| file.display().to_string())
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn suggestions_are_the_closest_names_within_a_typo() {
        assert_eq!(levenshtein("lio_sam", "lio-sam"), 1);
        assert_eq!(levenshtein("", "abc"), 3);
        assert_eq!(levenshtein("kitten", "sitting"), 3);
        let names = ["lio-sam", "rtabmap", "orbslam2", "wheel-odometry"].map(String::from);
        assert_eq!(closest("lio-slam", &names), Some("lio-sam"));
        assert_eq!(closest("orbslam3", &names), Some("orbslam2"));
        assert_eq!(closest("rtab", &names), None);
        assert_eq!(closest("nothing-like-it", &names), None);
        assert_eq!(
            name_of_file(Path::new("/x/libwheel_odometry.so")).as_deref(),
            Some("wheel-odometry")
        );
    }
}
