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
    let mut found = 0;
    for path in crate::plugins::candidates(&dirs) {
        match plugin_api::load(&path) {
            Ok(p) => {
                let sensors: Vec<&str> = p.requirements.sensors.iter().map(|k| k.name()).collect();
                let mode = match p.requirements.mode {
                    plugin_api::Mode::Online => "online",
                    plugin_api::Mode::Offline => "offline",
                };
                println!(
                    "{}\t{}\t{} [{}]\t{}",
                    p.name,
                    p.version,
                    mode,
                    sensors.join(","),
                    path.display()
                );
                found += 1;
            }
            // Other shared libraries in the same folders are not plugins: say nothing.
            Err(LoadError::Other { .. }) => {}
            Err(e) => println!("(unusable)\t{e}"),
        }
    }
    if found == 0 {
        let searched: Vec<String> = dirs.iter().map(|d| d.display().to_string()).collect();
        eprintln!("no plugins found in {}", searched.join(", "));
    }
    Ok(())
}
