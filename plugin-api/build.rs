//! Writes `export_plugin!` with the symbol name abi_stable's loader looks for. That name is
//! mangled by abi_stable's version and only computable in Rust, so the macro that exports a
//! plugin's root module (without the plugin depending on abi_stable itself) is generated.

use std::path::PathBuf;

fn main() {
    let name = abi_stable_shared::mangled_root_module_loader_name();
    let out = PathBuf::from(std::env::var_os("OUT_DIR").expect("cargo sets OUT_DIR"))
        .join("export_plugin.rs");
    let text = format!(
        r#"/// Exports `$ty` (a [`SlamSystem`]) as this library's plugin. Call it once, at the crate
/// root of a `cdylib` crate.
#[macro_export]
macro_rules! export_plugin {{
    ($ty:ty) => {{
        #[doc(hidden)]
        #[unsafe(export_name = "{name}")]
        pub static VINEBENCH_PLUGIN_ROOT: $crate::__private::abi_stable::library::LibHeader = {{
            extern "C" fn construct() -> $crate::__private::abi_stable::library::RootModuleResult {{
                $crate::__private::abi_stable::library::__call_root_module_loader($crate::__private::module::<$ty>)
            }}
            // SAFETY: `construct` returns the root module type named here, as the loader expects.
            unsafe {{
                $crate::__private::abi_stable::library::LibHeader::from_constructor::<$crate::__private::PluginModuleRef>(
                    construct,
                    $crate::__private::abi_stable::library::CheckTypeLayout::Yes,
                )
            }}
        }};
    }};
}}
"#
    );
    std::fs::write(&out, text).expect("write export_plugin.rs");
    println!("cargo:rerun-if-changed=build.rs");
}
