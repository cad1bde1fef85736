//! `vinebench plugins`: every plugin on the search path, one line each.

use std::path::PathBuf;

use clap::Args;
use plugin_api::LoadError;

#[derive(Debug, Args)]
pub struct PluginsArgs {
    /// More directories to search, before `VINEBENCH_PLUGIN_PATH` and the executable's directory.
    #[arg(long = "plugin-dir")]
    pub plugin_dirs: Vec<PathBuf>,
}

pub fn run(args: &PluginsArgs) -> anyhow::Result<()> {
    let dirs = crate::plugins::search_path(&args.plugin_dirs);
    let (mut found, mut broken, mut others) = (0, 0, 0);
    for path in crate::plugins::candidates(&dirs) {
        match plugin_api::load(&path) {
            Ok(p) => {
                let sensors: Vec<&str> = p.requirements.sensors.iter().map(|k| k.name()).collect();
                let mode = match p.requirements.mode {
                    plugin_api::Mode::Online => "online",
                    plugin_api::Mode::Offline => "offline",
                };
                // Whether it can localise in a saved map (`vinebench localize`).
                let localises = if p.requirements.can_localize {
                    " localises"
                } else {
                    ""
                };
                crate::out!(
                    "{}\t{}\t{} [{}]{localises}\t{}\t{}",
                    p.name,
                    p.version,
                    mode,
                    sensors.join(","),
                    p.door().name(),
                    path.display()
                );
                found += 1;
            }
            // Other shared libraries in the same folders are not plugins: counted, not listed.
            Err(LoadError::NotAPlugin { .. }) => others += 1,
            // A library that exports a plugin's symbol but cannot be used: listed with why.
            Err(e) => {
                crate::out!("(broken)\t{e}");
                broken += 1;
            }
        }
    }
    let searched: Vec<String> = dirs.iter().map(|d| d.display().to_string()).collect();
    if found == 0 {
        eprintln!("no plugins found in {}", searched.join(", "));
    }
    if broken > 0 || others > 0 {
        eprintln!(
            "{found} plugin(s), {broken} broken, {others} other librar{} (not plugins) in {}",
            if others == 1 { "y" } else { "ies" },
            searched.join(", ")
        );
    }
    Ok(())
}
