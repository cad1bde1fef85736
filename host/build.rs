//! Link flags for the end-to-end test binary.
//!
//! `tests/e2e` links the plugin crates (lio-sam, rtabmap, orbslam2, staticmapping) as
//! rlibs to test their parts directly, and each of them defines the exported static that
//! abi_stable's loader looks up in a plugin library, under the same symbol name. Built
//! with cross-crate LTO the unused statics vanish before linking; without it (the
//! `suite` profile) the linker sees one per plugin. The test binary never uses them (it
//! loads every plugin from its own `.so`), so any one may stand: tell the linker so, for
//! this package's integration tests only.

fn main() {
    println!("cargo::rustc-link-arg-tests=-Wl,--allow-multiple-definition");
    println!("cargo::rerun-if-changed=build.rs");
}
