//! The host side: loads a plugin library, checks it was built against this plugin-api, and
//! drives it. Each library is loaded through its own header (`lib_header_from_path`), so two
//! plugins in one process are two modules (`RootModule::load_from_file` would cache the
//! first one per module type).

use std::path::{Path, PathBuf};

use abi_stable::library::{LibraryError, lib_header_from_path};
use abi_stable::std_types::{ROption, RResult, RString};

use crate::c_abi::{CInstance, CPlugin};
use crate::ffi::{
    LaserScanFfi, MapStartFfi, PluginModuleRef, PointCloudFfi, RgbdFrameFfi, SlamBox,
    output_from_ffi, saved_map_from_ffi,
};
use crate::messages::{Gnss, Imu, LaserScan, PointCloud, Pose, RgbdFrame, WheelOdometry};
use crate::rig::Rig;
use crate::system::{MapStart, PluginError, PoseStatus, Requirements, SlamOutput};

/// Why a library could not be used as a plugin: one line naming the file.
#[derive(Debug, thiserror::Error)]
pub enum LoadError {
    #[error(
        "{path}: built against plugin-api {plugin}, but this vinebench has plugin-api {host}; rebuild the plugin against {host}"
    )]
    Version {
        path: PathBuf,
        plugin: String,
        host: String,
    },
    #[error(
        "{path}: the plugin-api types it was built with differ in layout from this vinebench's; rebuild the plugin against plugin-api {host}"
    )]
    Layout { path: PathBuf, host: String },
    /// A shared library that exports neither door's symbol: not a plugin at all.
    #[error(
        "{path}: not a vinebench plugin (it exports neither vinebench_plugin_v1 nor a Rust plugin's root module; did it call export_plugin!?)"
    )]
    NotAPlugin { path: PathBuf },
    #[error("{path}: {message}")]
    Other { path: PathBuf, message: String },
}

/// Through which door a library speaks.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Door {
    /// A Rust plugin (`export_plugin!`, abi_stable's root module).
    Rust,
    /// A C plugin (`vinebench_plugin_v1`, `include/vinebench_plugin.h`).
    C,
}

impl Door {
    pub fn name(self) -> &'static str {
        match self {
            Door::Rust => "Rust",
            Door::C => "C",
        }
    }
}

/// A loaded plugin library, not yet created.
#[derive(Debug, Clone)]
pub struct LoadedPlugin {
    pub path: PathBuf,
    pub name: String,
    pub version: String,
    pub requirements: Requirements,
    module: Module,
}

/// Which ABI a library speaks.
#[derive(Clone)]
enum Module {
    Rust(PluginModuleRef),
    C(CPlugin),
}

impl std::fmt::Debug for Module {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            Module::Rust(_) => "Module::Rust",
            Module::C(_) => "Module::C",
        })
    }
}

impl std::fmt::Debug for PluginModuleRef {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str("PluginModuleRef")
    }
}

fn first_line(text: &str) -> String {
    text.lines()
        .find(|l| !l.trim().is_empty())
        .unwrap_or("")
        .trim()
        .to_owned()
}

fn describe(path: &Path, e: LibraryError) -> LoadError {
    let host = crate::API_VERSION.to_owned();
    match e {
        LibraryError::IncompatibleVersionNumber { actual_version, .. } => LoadError::Version {
            path: path.to_owned(),
            plugin: actual_version.to_string(),
            host,
        },
        LibraryError::AbiInstability(_) => LoadError::Layout {
            path: path.to_owned(),
            host,
        },
        LibraryError::GetSymbolError { .. } => LoadError::NotAPlugin {
            path: path.to_owned(),
        },
        other => LoadError::Other {
            path: path.to_owned(),
            message: first_line(&other.to_string()),
        },
    }
}

/// `major.minor` of a version string: plugin-api versions that share it are compatible
/// (semver for 0.x releases: a new minor version may change the ABI).
fn compatible_part(version: &str) -> &str {
    let mut dots = version.match_indices('.');
    match (dots.next(), dots.next()) {
        (Some(_), Some((second, _))) => &version[..second],
        _ => version,
    }
}

/// Loads the plugin library at `path`: a C plugin (it exports `vinebench_plugin_v1`) or a
/// Rust one (abi_stable's root module).
pub fn load(path: &Path) -> Result<LoadedPlugin, LoadError> {
    let other = |message: String| LoadError::Other {
        path: path.to_owned(),
        message,
    };
    if let Some(c) = CPlugin::open(path).map_err(|m| other(first_line(&m)))? {
        return Ok(LoadedPlugin {
            path: path.to_owned(),
            name: c.name,
            version: c.version,
            requirements: c.requirements,
            module: Module::C(c.plugin),
        });
    }
    let header = lib_header_from_path(path).map_err(|e| describe(path, e))?;
    // Compare versions before layouts: a version mismatch is the clearer message.
    let plugin_version = header.version_strings().version.as_str();
    if compatible_part(plugin_version) != compatible_part(crate::API_VERSION) {
        return Err(LoadError::Version {
            path: path.to_owned(),
            plugin: plugin_version.to_owned(),
            host: crate::API_VERSION.to_owned(),
        });
    }
    let module = header
        .init_root_module::<PluginModuleRef>()
        .map_err(|e| describe(path, e))?;
    let info = (module.info())();
    let requirements = match info.requirements_toml {
        RResult::ROk(text) => toml::from_str(&text).map_err(|e| LoadError::Other {
            path: path.to_owned(),
            message: format!("unreadable requirements: {}", e.message()),
        })?,
        RResult::RErr(e) => {
            return Err(LoadError::Other {
                path: path.to_owned(),
                message: format!("requirements() failed: {e}"),
            });
        }
    };
    Ok(LoadedPlugin {
        path: path.to_owned(),
        name: info.name.into_string(),
        version: info.version.into_string(),
        requirements,
        module: Module::Rust(module),
    })
}

impl LoadedPlugin {
    /// Through which door the library speaks.
    pub fn door(&self) -> Door {
        match self.module {
            Module::Rust(_) => Door::Rust,
            Module::C(_) => Door::C,
        }
    }

    /// The requirements for this parameter table: the plugin's answer when it takes the
    /// parameters into account (a Rust plugin's [`crate::SlamSystem::requirements_for`], a
    /// C plugin's `requirements_for`), else the requirements it gave when loaded (plugins
    /// built before either existed).
    pub fn requirements_for(&self, config_toml: &str) -> Result<Requirements, PluginError> {
        let module = match &self.module {
            Module::C(c) => return c.requirements_for(config_toml, &self.requirements),
            Module::Rust(module) => module,
        };
        let Some(ask) = module.requirements_for() else {
            return Ok(self.requirements.clone());
        };
        match ask(config_toml.into()) {
            RResult::ROk(text) => toml::from_str(text.as_str())
                .map_err(|e| PluginError(format!("unreadable requirements: {}", e.message()))),
            RResult::RErr(e) => Err(PluginError(format!(
                "requirements failed: {}",
                e.into_string()
            ))),
        }
    }

    /// Creates the system with its parameter table (TOML, verbatim) and the rig.
    pub fn create(&self, config_toml: &str, rig: &Rig) -> Result<PluginInstance, PluginError> {
        match &self.module {
            Module::Rust(module) => {
                let create = module.create();
                match create(config_toml.into(), rig.to_toml().as_str().into()) {
                    RResult::ROk(inner) => Ok(PluginInstance::Rust(inner)),
                    RResult::RErr(e) => Err(PluginError(e.into_string())),
                }
            }
            Module::C(c) => c.create(config_toml, rig, None).map(PluginInstance::C),
        }
    }

    /// Creates the system in localisation mode from a saved map (revision 4). A plugin that
    /// does not say `can_localize` for these parameters, or was built before the call
    /// existed, is refused with a line saying so.
    pub fn create_localizing(
        &self,
        config_toml: &str,
        rig: &Rig,
        start: &MapStart<'_>,
    ) -> Result<PluginInstance, PluginError> {
        if !self.requirements_for(config_toml)?.can_localize {
            return Err(PluginError(format!(
                "{} cannot localise in a saved map (its requirements do not say can_localize)",
                self.name
            )));
        }
        match &self.module {
            Module::Rust(module) => {
                let Some(create) = module.create_localizing() else {
                    return Err(PluginError(format!(
                        "{} was built before plugins could localise (plugin-api revision < 4)",
                        self.name
                    )));
                };
                let ffi = MapStartFfi {
                    map: start.map.into(),
                    format: start.format.into(),
                    format_version: start.format_version,
                    initial_guess: start.initial_guess.into(),
                };
                match create(config_toml.into(), rig.to_toml().as_str().into(), ffi) {
                    RResult::ROk(inner) => Ok(PluginInstance::Rust(inner)),
                    RResult::RErr(e) => Err(PluginError(e.into_string())),
                }
            }
            Module::C(c) => c
                .create(config_toml, rig, Some(start))
                .map(PluginInstance::C),
        }
    }
}

/// A created plugin, driven by the host: either kind, the same calls.
pub enum PluginInstance {
    Rust(SlamBox),
    C(CInstance),
}

impl std::fmt::Debug for PluginInstance {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str("PluginInstance")
    }
}

fn pose(r: RResult<ROption<Pose>, RString>) -> Result<Option<Pose>, PluginError> {
    match r {
        RResult::ROk(p) => Ok(p.into_option()),
        RResult::RErr(e) => Err(PluginError(e.into_string())),
    }
}

impl PluginInstance {
    pub fn on_imu(&mut self, imu: &Imu) -> Result<Option<Pose>, PluginError> {
        match self {
            Self::Rust(inner) => pose(inner.on_imu(imu)),
            Self::C(c) => c.on_imu(imu),
        }
    }

    pub fn on_wheel_odometry(&mut self, odom: &WheelOdometry) -> Result<Option<Pose>, PluginError> {
        match self {
            Self::Rust(inner) => pose(inner.on_wheel_odometry(odom)),
            Self::C(c) => c.on_wheel_odometry(odom),
        }
    }

    pub fn on_point_cloud(&mut self, c: &PointCloud<'_>) -> Result<Option<Pose>, PluginError> {
        let inner = match self {
            Self::Rust(inner) => inner,
            Self::C(instance) => return instance.on_point_cloud(c),
        };
        pose(inner.on_point_cloud(PointCloudFfi {
            stamp_ns: c.stamp_ns,
            sensor: c.sensor.into(),
            points: c.points.into(),
        }))
    }

    pub fn on_laser_scan(&mut self, s: &LaserScan<'_>) -> Result<Option<Pose>, PluginError> {
        let inner = match self {
            Self::Rust(inner) => inner,
            Self::C(instance) => return instance.on_laser_scan(s),
        };
        pose(inner.on_laser_scan(LaserScanFfi {
            stamp_ns: s.stamp_ns,
            sensor: s.sensor.into(),
            angle_min_rad: s.angle_min_rad,
            angle_increment_rad: s.angle_increment_rad,
            time_increment_s: s.time_increment_s,
            range_min_m: s.range_min_m,
            range_max_m: s.range_max_m,
            ranges_m: s.ranges_m.into(),
            intensities: s.intensities.into(),
        }))
    }

    pub fn on_rgbd(&mut self, f: &RgbdFrame<'_>) -> Result<Option<Pose>, PluginError> {
        let inner = match self {
            Self::Rust(inner) => inner,
            Self::C(instance) => return instance.on_rgbd(f),
        };
        pose(inner.on_rgbd(RgbdFrameFfi {
            stamp_ns: f.stamp_ns,
            sensor: f.sensor.into(),
            width: f.width,
            height: f.height,
            rgb: f.rgb.into(),
            depth_m: f.depth_m.into(),
            intrinsics: f.intrinsics,
        }))
    }

    /// A GNSS epoch (revision 5).
    pub fn on_gnss(&mut self, gnss: &Gnss) -> Result<Option<Pose>, PluginError> {
        match self {
            Self::Rust(inner) => pose(inner.on_gnss(gnss)),
            Self::C(c) => c.on_gnss(gnss),
        }
    }

    /// The status of the pose last returned (revision 4; plugins built before it:
    /// localised).
    pub fn status(&self) -> PoseStatus {
        match self {
            Self::Rust(inner) => inner.status(),
            Self::C(c) => c.status(),
        }
    }

    /// The final output, with the map the plugin saved (revision 4).
    pub fn finish(&mut self) -> Result<SlamOutput, PluginError> {
        match self {
            Self::Rust(inner) => match inner.finish() {
                RResult::ROk(o) => {
                    let mut output = output_from_ffi(o).map_err(PluginError)?;
                    output.saved_map = inner.take_saved_map().into_option().map(saved_map_from_ffi);
                    Ok(output)
                }
                RResult::RErr(e) => Err(PluginError(e.into_string())),
            },
            Self::C(c) => c.finish(),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::compatible_part;

    #[test]
    fn compatibility_is_major_and_minor() {
        assert_eq!(compatible_part("0.1.7"), "0.1");
        assert_eq!(compatible_part("1.2.3-rc.1"), "1.2");
        assert_ne!(compatible_part("0.2.0"), compatible_part("0.1.0"));
    }
}
