//! Link flags for the end-to-end test binary, and the C plugin the tests load.
//!
//! `tests/e2e` links the plugin crates (lio-sam, rtabmap, orbslam2, staticmapping) as
//! rlibs to test their parts directly, and each of them defines the exported static that
//! abi_stable's loader looks up in a plugin library, under the same symbol name. Built
//! with cross-crate LTO the unused statics vanish before linking; without it (the
//! `suite` profile) the linker sees one per plugin. The test binary never uses them (it
//! loads every plugin from its own `.so`), so any one may stand: tell the linker so, for
//! this package's integration tests only.

//!
//! `tests/c-plugin/c_odometry.c` is a plugin written against the C ABI
//! (`plugin-api/include/vinebench_plugin.h`); it is compiled here with the C compiler the
//! `cc` crate finds, into `$OUT_DIR`, and its path handed to the tests as
//! `VINEBENCH_C_ODOMETRY`; `tests/c-plugin/c_noop.c`, the no-op of the bridges' benchmark,
//! as `VINEBENCH_C_NOOP`.

use std::path::Path;

fn main() {
    println!("cargo::rustc-link-arg-tests=-Wl,--allow-multiple-definition");
    println!("cargo::rustc-link-arg-benches=-Wl,--allow-multiple-definition");
    println!("cargo::rerun-if-changed=build.rs");
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("..");
    let include = root.join("plugin-api/include");
    println!(
        "cargo::rerun-if-changed={}",
        include.join("vinebench_plugin.h").display()
    );
    let out_dir = std::env::var("OUT_DIR").expect("cargo sets OUT_DIR");
    let compiler = cc::Build::new().get_compiler();
    // The odometry plugin, the same claiming ABI version 99, and the no-op plugin of the
    // bridges' benchmark, each in a folder of its own (so that the good one's folder holds
    // only it).
    for (stem, folder, define, variable) in [
        ("c_odometry", "c-plugin", None, "VINEBENCH_C_ODOMETRY"),
        (
            "c_odometry",
            "c-plugin-v99",
            Some("-DC_ODOMETRY_ABI_VERSION=99"),
            "VINEBENCH_C_ODOMETRY_V99",
        ),
        (
            "c_odometry",
            "c-plugin-revision-1",
            Some("-DC_ODOMETRY_REVISION_1"),
            "VINEBENCH_C_ODOMETRY_REVISION_1",
        ),
        ("c_noop", "c-noop", None, "VINEBENCH_C_NOOP"),
    ] {
        let source = root.join(format!("tests/c-plugin/{stem}.c"));
        println!("cargo::rerun-if-changed={}", source.display());
        let dir = Path::new(&out_dir).join(folder);
        std::fs::create_dir_all(&dir).expect("create the C plugin's folder");
        let out = dir.join(format!(
            "{}{stem}{}",
            std::env::consts::DLL_PREFIX,
            std::env::consts::DLL_SUFFIX
        ));
        let mut command = compiler.to_command();
        command
            .args([
                "-shared",
                "-fPIC",
                "-O2",
                "-std=c11",
                "-Wall",
                "-Wextra",
                "-Werror",
                "-ffp-contract=off",
            ])
            .arg("-I")
            .arg(&include)
            .args(define);
        let status = command
            .arg(&source)
            .arg("-o")
            .arg(&out)
            .arg("-lm")
            .status()
            .expect("the C compiler runs");
        assert!(status.success(), "compiling {} failed", source.display());
        println!("cargo::rustc-env={variable}={}", out.display());
    }
}
