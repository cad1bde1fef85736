//! What the end-to-end plugin tests share: running a plugin through the `vinebench` binary
//! and reading what it wrote.

use std::path::{Path, PathBuf};
use std::process::Command;

/// Where cargo put the test's libraries, the plugins' `.so` among them.
pub fn deps_dir() -> PathBuf {
    std::env::current_exe()
        .expect("test executable")
        .parent()
        .expect("deps directory")
        .to_owned()
}

pub fn json(path: &Path) -> serde_json::Value {
    let t = std::fs::read_to_string(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    serde_json::from_str(&t).unwrap_or_else(|e| panic!("{}: {e}", path.display()))
}

/// Runs `plugin` through the host on a scenario with `params` as its configuration;
/// returns its results folder.
pub fn run(dir: &Path, scenario: &str, plugin: &str, label: &str, params: &str) -> PathBuf {
    let config = dir.join(format!("{label}.toml"));
    std::fs::write(&config, params).expect("write plugin config");
    let out = dir.join(label);
    let o = Command::new(env!("CARGO_BIN_EXE_vinebench"))
        .args([
            "run",
            "--scenario",
            scenario,
            "--plugin",
            plugin,
            "--plugin-config",
        ])
        .arg(&config)
        .arg("--out")
        .arg(&out)
        .env("VINEBENCH_PLUGIN_PATH", deps_dir())
        .output()
        .expect("vinebench runs");
    assert!(
        o.status.success(),
        "run {label} failed: {}",
        String::from_utf8_lossy(&o.stderr)
    );
    out.join(scenario).join(plugin)
}

/// ATE of a TUM trajectory against ground truth (SE(3) alignment), from `vinebench eval`.
pub fn ate(folder: &Path, file: &str) -> f64 {
    let o = Command::new(env!("CARGO_BIN_EXE_vinebench"))
        .args(["eval", "--align", "se3", "--json"])
        .arg(folder.join("groundtruth.tum"))
        .arg(folder.join(file))
        .output()
        .expect("vinebench eval runs");
    assert!(
        o.status.success(),
        "eval failed: {}",
        String::from_utf8_lossy(&o.stderr)
    );
    serde_json::from_slice::<serde_json::Value>(&o.stdout).expect("json")["rmse"]
        .as_f64()
        .expect("rmse")
}
