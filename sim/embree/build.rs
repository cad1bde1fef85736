//! Links the system's libembree3 (Debian: libembree-dev, installed by scripts/setup.sh).
//! Looks in EMBREE_LIB_DIR if set, else in the usual library directories, and stops with one
//! line saying what to install when the library is not there. Where the header is found it
//! also checks the two build settings the hand-written declarations in src/sys.rs assume.

use std::path::{Path, PathBuf};

fn main() {
    println!("cargo::rerun-if-changed=build.rs");
    println!("cargo::rerun-if-env-changed=EMBREE_LIB_DIR");
    println!("cargo::rerun-if-env-changed=EMBREE_INCLUDE_DIR");
    let arch = std::env::var("CARGO_CFG_TARGET_ARCH").unwrap_or_default();
    let os = std::env::var("CARGO_CFG_TARGET_OS").unwrap_or_default();
    let (lib_file, multiarch) = match os.as_str() {
        "macos" => ("libembree3.dylib", None),
        _ => ("libembree3.so", Some(format!("/usr/lib/{arch}-linux-gnu"))),
    };
    let candidates: Vec<PathBuf> = match std::env::var_os("EMBREE_LIB_DIR") {
        Some(dir) => vec![PathBuf::from(dir)],
        None => multiarch
            .into_iter()
            .chain(
                [
                    "/usr/lib64",
                    "/usr/lib",
                    "/usr/local/lib",
                    "/opt/homebrew/lib",
                ]
                .map(String::from),
            )
            .map(PathBuf::from)
            .collect(),
    };
    let Some(dir) = candidates.iter().find(|d| d.join(lib_file).exists()) else {
        fail(&format!(
            "{lib_file} not found in {}: install Debian's libembree-dev (bash scripts/setup.sh does), set EMBREE_LIB_DIR, or build vinebench-sim without its `embree` feature",
            candidates
                .iter()
                .map(|d| d.display().to_string())
                .collect::<Vec<_>>()
                .join(", ")
        ));
    };
    println!("cargo::rustc-link-search=native={}", dir.display());
    println!("cargo::rustc-link-lib=dylib=embree3");

    let include = std::env::var_os("EMBREE_INCLUDE_DIR")
        .map(PathBuf::from)
        .unwrap_or_else(|| dir.join("../../include"));
    let config = [
        include.join("embree3/rtcore_config.h"),
        PathBuf::from("/usr/include/embree3/rtcore_config.h"),
    ]
    .into_iter()
    .find(|p| p.exists());
    if let Some(config) = config {
        check_header(&config);
    }
}

/// src/sys.rs lays RTCHit and RTCIntersectContext out for one instance level and no minimum
/// width; a library built otherwise would read past our structs.
fn check_header(path: &Path) {
    let text = std::fs::read_to_string(path).unwrap_or_default();
    for (name, want) in [
        ("RTC_MAX_INSTANCE_LEVEL_COUNT", "1"),
        ("EMBREE_MIN_WIDTH", "0"),
    ] {
        let got = text
            .lines()
            .filter_map(|l| l.trim().strip_prefix("#define "))
            .find_map(|l| l.strip_prefix(name).map(str::trim));
        if got.is_some_and(|g| g != want) {
            fail(&format!(
                "{}: {name} is {}, but src/sys.rs is written for {want}",
                path.display(),
                got.unwrap_or_default()
            ));
        }
    }
}

/// `cargo::error` fails the build with exactly this line (and nothing else to read through).
fn fail(message: &str) -> ! {
    println!("cargo::error={message}");
    // A build script reports its failure through `cargo::error` and then stops.
    #[allow(clippy::disallowed_methods)]
    std::process::exit(0);
}
