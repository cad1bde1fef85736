//! The stable-ABI mirror of the plugin API (abi_stable): the root module every plugin
//! exports, the trait object the host drives, and the adapter that wraps an author's
//! [`SlamSystem`] with panic catching. Nothing here is part of the author's API; it is public
//! only for [`crate::export_plugin!`] and the loader.
//!
//! The root module is a prefix type: later versions may only append fields after the one
//! marked `last_prefix_field` (and methods after `finish` in [`SlamFfi`]).

// Mirror types are plain data for the FFI; the author-side types carry the Debug impls.
#![allow(missing_debug_implementations)]
// `#[sabi_trait]` repeats the supertrait path in its expansion.
#![allow(unused_qualifications)]
// ... and implements its generated interface trait inside a generated const block.
#![allow(non_local_definitions)]

use std::panic::{AssertUnwindSafe, catch_unwind};

use abi_stable::library::RootModule;
use abi_stable::prefix_type::PrefixTypeTrait;
use abi_stable::sabi_trait::TD_Opaque;
use abi_stable::sabi_types::VersionStrings;
use abi_stable::std_types::{RBox, ROption, RResult, RSlice, RStr, RString, RVec};
use abi_stable::{StableAbi, declare_root_module_statics, package_version_strings, sabi_trait};

use crate::messages::{
    Gnss, Imu, LaserScan, LidarPoint, PointCloud, Pose, RgbdFrame, WheelOdometry,
};
use crate::rig::Rig;
use crate::system::{
    Event, InitialGuess, MapStart, OccupancyGrid, PluginError, PoseStatus, SavedMap, SlamOutput,
    SlamSystem,
};

/// What a plugin says about itself before it is created.
#[repr(C)]
#[derive(StableAbi, Debug)]
pub struct PluginInfoFfi {
    pub name: RString,
    pub version: RString,
    /// [`crate::Requirements`] as TOML, or an error message if asking for them failed.
    pub requirements_toml: RResult<RString, RString>,
}

/// The root module of every plugin library.
#[repr(C)]
#[derive(StableAbi)]
#[sabi(kind(Prefix(prefix_ref = PluginModuleRef)))]
#[sabi(missing_field(panic))]
pub struct PluginModule {
    pub info: extern "C" fn() -> PluginInfoFfi,
    #[sabi(last_prefix_field)]
    pub create:
        extern "C" fn(config_toml: RStr<'_>, rig_toml: RStr<'_>) -> RResult<SlamBox, RString>,
    /// [`crate::Requirements`] as TOML for a parameter table (appended: absent from plugins
    /// built before it, whose `info` requirements then stand).
    #[sabi(missing_field(option))]
    pub requirements_for: extern "C" fn(config_toml: RStr<'_>) -> RResult<RString, RString>,
    /// Creates the system in localisation mode from a saved map (revision 4; absent from
    /// plugins built before it, which cannot localise).
    #[sabi(missing_field(option))]
    pub create_localizing: extern "C" fn(
        config_toml: RStr<'_>,
        rig_toml: RStr<'_>,
        start: MapStartFfi<'_>,
    ) -> RResult<SlamBox, RString>,
}

/// [`crate::MapStart`] across the ABI.
#[repr(C)]
#[derive(StableAbi, Clone, Copy)]
pub struct MapStartFfi<'a> {
    pub map: RSlice<'a, u8>,
    pub format: RStr<'a>,
    pub format_version: u32,
    pub initial_guess: ROption<InitialGuess>,
}

/// [`crate::SavedMap`] across the ABI.
#[repr(C)]
#[derive(StableAbi)]
pub struct SavedMapFfi {
    pub format: RString,
    pub version: u32,
    pub bytes: RVec<u8>,
}

impl RootModule for PluginModuleRef {
    declare_root_module_statics! {PluginModuleRef}
    const BASE_NAME: &'static str = "vinebench_plugin";
    const NAME: &'static str = "vinebench_plugin";
    // plugin-api's own Cargo version: a plugin built against another one is refused.
    const VERSION_STRINGS: VersionStrings = package_version_strings!();
}

#[repr(C)]
#[derive(StableAbi, Clone, Copy)]
pub struct PointCloudFfi<'a> {
    pub stamp_ns: i64,
    pub sensor: RStr<'a>,
    pub points: RSlice<'a, LidarPoint>,
}

#[repr(C)]
#[derive(StableAbi, Clone, Copy)]
pub struct LaserScanFfi<'a> {
    pub stamp_ns: i64,
    pub sensor: RStr<'a>,
    pub angle_min_rad: f32,
    pub angle_increment_rad: f32,
    pub time_increment_s: f32,
    pub range_min_m: f32,
    pub range_max_m: f32,
    pub ranges_m: RSlice<'a, f32>,
    pub intensities: RSlice<'a, f32>,
}

#[repr(C)]
#[derive(StableAbi, Clone, Copy)]
pub struct RgbdFrameFfi<'a> {
    pub stamp_ns: i64,
    pub sensor: RStr<'a>,
    pub width: u32,
    pub height: u32,
    pub rgb: RSlice<'a, u8>,
    pub depth_m: RSlice<'a, f32>,
    pub intrinsics: [f64; 4],
}

#[repr(C)]
#[derive(StableAbi)]
pub struct GridFfi {
    pub resolution_m: f64,
    pub origin: [f64; 3],
    pub width: u32,
    pub height: u32,
    pub cells: RVec<i8>,
}

#[repr(C)]
#[derive(StableAbi)]
pub struct OutputFfi {
    pub trajectory: RVec<Pose>,
    pub map: ROption<RVec<[f32; 3]>>,
    pub grid: ROption<GridFfi>,
    /// The events as TOML (`[[events]]` tables), extensible without a layout change.
    pub events_toml: RString,
}

/// The calls the host makes on a created plugin; every one returns an error string instead
/// of unwinding.
#[sabi_trait]
pub trait SlamFfi: Send {
    fn on_imu(&mut self, imu: &Imu) -> RResult<ROption<Pose>, RString>;
    fn on_wheel_odometry(&mut self, odom: &WheelOdometry) -> RResult<ROption<Pose>, RString>;
    fn on_point_cloud(&mut self, cloud: PointCloudFfi<'_>) -> RResult<ROption<Pose>, RString>;
    fn on_laser_scan(&mut self, scan: LaserScanFfi<'_>) -> RResult<ROption<Pose>, RString>;
    fn on_rgbd(&mut self, frame: RgbdFrameFfi<'_>) -> RResult<ROption<Pose>, RString>;
    #[sabi(last_prefix_field)]
    fn finish(&mut self) -> RResult<OutputFfi, RString>;
    /// Revision 4: the status of the pose last returned. The default is what a plugin built
    /// before it gets (abi_stable calls a default method missing from an older vtable).
    fn status(&self) -> PoseStatus {
        PoseStatus::Localized
    }
    /// Revision 4: the map `finish` saved, once, after `finish`.
    fn take_saved_map(&mut self) -> ROption<SavedMapFfi> {
        ROption::RNone
    }
    /// Revision 5: a GNSS epoch. The default (a plugin built before it, which never asks for
    /// GNSS) ignores it.
    fn on_gnss(&mut self, gnss: &Gnss) -> RResult<ROption<Pose>, RString> {
        let _ = gnss;
        RResult::ROk(ROption::RNone)
    }
}

/// A created plugin behind the stable ABI.
pub type SlamBox = SlamFfi_TO<'static, RBox<()>>;

/// Runs `f`, turning a panic into an error message.
fn guard<T>(f: impl FnOnce() -> Result<T, PluginError>) -> Result<T, String> {
    match catch_unwind(AssertUnwindSafe(f)) {
        Ok(Ok(v)) => Ok(v),
        Ok(Err(e)) => Err(e.0),
        Err(payload) => {
            let message = payload
                .downcast_ref::<&str>()
                .map(|s| (*s).to_owned())
                .or_else(|| payload.downcast_ref::<String>().cloned())
                .unwrap_or_else(|| "a non-string payload".to_owned());
            Err(format!("panicked: {message}"))
        }
    }
}

fn pose_result(r: Result<Option<Pose>, String>) -> RResult<ROption<Pose>, RString> {
    r.map(ROption::from).map_err(RString::from).into()
}

/// Wraps an author's system for the ABI, keeping the map its `finish` saved until the host
/// takes it.
#[derive(Debug)]
pub struct Adapter<T>(T, Option<SavedMap>);

impl<T: SlamSystem> SlamFfi for Adapter<T> {
    fn on_imu(&mut self, imu: &Imu) -> RResult<ROption<Pose>, RString> {
        pose_result(guard(|| self.0.on_imu(imu)))
    }

    fn on_wheel_odometry(&mut self, odom: &WheelOdometry) -> RResult<ROption<Pose>, RString> {
        pose_result(guard(|| self.0.on_wheel_odometry(odom)))
    }

    fn on_point_cloud(&mut self, c: PointCloudFfi<'_>) -> RResult<ROption<Pose>, RString> {
        let cloud = PointCloud {
            stamp_ns: c.stamp_ns,
            sensor: c.sensor.as_str(),
            points: c.points.as_slice(),
        };
        pose_result(guard(|| self.0.on_point_cloud(&cloud)))
    }

    fn on_laser_scan(&mut self, s: LaserScanFfi<'_>) -> RResult<ROption<Pose>, RString> {
        let scan = LaserScan {
            stamp_ns: s.stamp_ns,
            sensor: s.sensor.as_str(),
            angle_min_rad: s.angle_min_rad,
            angle_increment_rad: s.angle_increment_rad,
            time_increment_s: s.time_increment_s,
            range_min_m: s.range_min_m,
            range_max_m: s.range_max_m,
            ranges_m: s.ranges_m.as_slice(),
            intensities: s.intensities.as_slice(),
        };
        pose_result(guard(|| self.0.on_laser_scan(&scan)))
    }

    fn on_rgbd(&mut self, f: RgbdFrameFfi<'_>) -> RResult<ROption<Pose>, RString> {
        let frame = RgbdFrame {
            stamp_ns: f.stamp_ns,
            sensor: f.sensor.as_str(),
            width: f.width,
            height: f.height,
            rgb: f.rgb.as_slice(),
            depth_m: f.depth_m.as_slice(),
            intrinsics: f.intrinsics,
        };
        pose_result(guard(|| self.0.on_rgbd(&frame)))
    }

    fn finish(&mut self) -> RResult<OutputFfi, RString> {
        guard(|| self.0.finish())
            .map(|mut output| {
                self.1 = output.saved_map.take();
                output_to_ffi(output)
            })
            .map_err(RString::from)
            .into()
    }

    fn status(&self) -> PoseStatus {
        // A panic here cannot be reported as an error: it counts as searching.
        catch_unwind(AssertUnwindSafe(|| self.0.status())).unwrap_or(PoseStatus::Searching)
    }

    fn on_gnss(&mut self, gnss: &Gnss) -> RResult<ROption<Pose>, RString> {
        pose_result(guard(|| self.0.on_gnss(gnss)))
    }

    fn take_saved_map(&mut self) -> ROption<SavedMapFfi> {
        self.1
            .take()
            .map(|m| SavedMapFfi {
                format: m.format.into(),
                version: m.version,
                bytes: m.bytes.into(),
            })
            .into()
    }
}

/// Back to the author-side type (host side).
pub fn saved_map_from_ffi(m: SavedMapFfi) -> SavedMap {
    SavedMap {
        format: m.format.into_string(),
        version: m.version,
        bytes: m.bytes.into_vec(),
    }
}

#[derive(serde::Serialize, serde::Deserialize)]
struct Events {
    #[serde(default)]
    events: Vec<Event>,
}

fn output_to_ffi(o: SlamOutput) -> OutputFfi {
    OutputFfi {
        trajectory: o.trajectory.into(),
        map: o.map.map(RVec::from).into(),
        grid: o
            .grid
            .map(|g| GridFfi {
                resolution_m: g.resolution_m,
                origin: g.origin,
                width: g.width,
                height: g.height,
                cells: g.cells.into(),
            })
            .into(),
        events_toml: toml::to_string(&Events { events: o.events })
            .expect("events serialise")
            .into(),
    }
}

/// The events of a plugin's output, as both ABIs carry them: TOML `[[events]]` tables.
pub fn events_from_toml(text: &str) -> Result<Vec<Event>, String> {
    toml::from_str::<Events>(text)
        .map(|e| e.events)
        .map_err(|e| format!("events: {}", e.message()))
}

/// Back to the author-side type (host side).
pub fn output_from_ffi(o: OutputFfi) -> Result<SlamOutput, String> {
    let events = events_from_toml(&o.events_toml)?;
    Ok(SlamOutput {
        trajectory: o.trajectory.into_vec(),
        map: o.map.into_option().map(RVec::into_vec),
        grid: o.grid.into_option().map(|g| OccupancyGrid {
            resolution_m: g.resolution_m,
            origin: g.origin,
            width: g.width,
            height: g.height,
            cells: g.cells.into_vec(),
        }),
        events,
        saved_map: None,
    })
}

extern "C" fn info<T: SlamSystem>() -> PluginInfoFfi {
    let requirements = guard(|| Ok(T::requirements()))
        .and_then(|r| toml::to_string(&r).map_err(|e| e.to_string()))
        .map(RString::from)
        .map_err(RString::from);
    PluginInfoFfi {
        name: T::NAME.into(),
        version: T::VERSION.into(),
        requirements_toml: requirements.into(),
    }
}

extern "C" fn requirements_for<T: SlamSystem>(config_toml: RStr<'_>) -> RResult<RString, RString> {
    guard(|| T::requirements_for(config_toml.as_str()))
        .and_then(|r| toml::to_string(&r).map_err(|e| e.to_string()))
        .map(RString::from)
        .map_err(RString::from)
        .into()
}

extern "C" fn create<T: SlamSystem>(
    config_toml: RStr<'_>,
    rig_toml: RStr<'_>,
) -> RResult<SlamBox, RString> {
    guard(|| {
        let rig = Rig::from_toml(rig_toml.as_str()).map_err(PluginError)?;
        T::new(config_toml.as_str(), &rig)
    })
    .map(|system| SlamFfi_TO::from_value(Adapter(system, None), TD_Opaque))
    .map_err(RString::from)
    .into()
}

extern "C" fn create_localizing<T: SlamSystem>(
    config_toml: RStr<'_>,
    rig_toml: RStr<'_>,
    start: MapStartFfi<'_>,
) -> RResult<SlamBox, RString> {
    guard(|| {
        let rig = Rig::from_toml(rig_toml.as_str()).map_err(PluginError)?;
        let start = MapStart {
            map: start.map.as_slice(),
            format: start.format.as_str(),
            format_version: start.format_version,
            initial_guess: start.initial_guess.into_option(),
        };
        T::localize(config_toml.as_str(), &rig, &start)
    })
    .map(|system| SlamFfi_TO::from_value(Adapter(system, None), TD_Opaque))
    .map_err(RString::from)
    .into()
}

/// The root module for `T`; called by [`crate::export_plugin!`].
pub fn module<T: SlamSystem>() -> PluginModuleRef {
    PluginModule {
        info: info::<T>,
        create: create::<T>,
        requirements_for: requirements_for::<T>,
        create_localizing: create_localizing::<T>,
    }
    .leak_into_prefix()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::system::EventKind;

    /// Events cross the ABI as TOML: the loop stamps, relative pose and matches survive the
    /// trip, and a plugin that sends none (built before they existed) still loads.
    #[test]
    fn loop_stamps_cross_the_abi_and_may_be_absent() {
        let events = vec![
            Event::loop_closure(
                2_000_000_000,
                EventKind::LoopClosureAccepted,
                [2_000_000_000, 500_000_000],
                "keyframe 20 to 5",
            )
            .with_relative_pose(&nalgebra::Isometry3::new(
                nalgebra::Vector3::new(0.5, -3.0, 0.01),
                nalgebra::Vector3::new(0.0, 0.0, 0.2),
            ))
            .with_matches(vec![[10.5, 20.25, 300.0, 41.75], [0.0, 479.5, 639.5, 0.0]]),
            Event::new(2_100_000_000, EventKind::TrackingLost, "no features"),
        ];
        let output = SlamOutput {
            events: events.clone(),
            ..SlamOutput::default()
        };
        let ffi = output_to_ffi(output);
        assert!(
            ffi.events_toml
                .as_str()
                .contains("loop_stamps_ns = [2000000000, 500000000]"),
            "{}",
            ffi.events_toml
        );
        let back = output_from_ffi(ffi).expect("events parse");
        assert_eq!(back.events, events);
        assert_eq!(
            back.events[0].loop_stamps_ns,
            Some([2_000_000_000, 500_000_000])
        );
        assert_eq!(back.events[1].loop_stamps_ns, None);
        let pose = back.events[0]
            .relative_pose()
            .expect("the relative pose crosses");
        assert!((pose.translation.vector - nalgebra::Vector3::new(0.5, -3.0, 0.01)).norm() < 1e-12);
        assert!((pose.rotation.angle() - 0.2).abs() < 1e-12);
        assert_eq!(back.events[1].relative_pose(), None);
        assert_eq!(
            back.events[0].matches(),
            Some(&[[10.5, 20.25, 300.0, 41.75], [0.0, 479.5, 639.5, 0.0]][..])
        );
        assert_eq!(back.events[1].matches(), None);

        let old = OutputFfi {
            trajectory: RVec::new(),
            map: None.into(),
            grid: None.into(),
            events_toml:
                "[[events]]\nstamp_ns = 7\nkind = \"loop_closure_accepted\"\ndetail = \"old\"\n"
                    .into(),
        };
        let back = output_from_ffi(old).expect("an old plugin's events parse");
        assert_eq!(
            back.events,
            [Event::new(7, EventKind::LoopClosureAccepted, "old")]
        );
    }
}
