//! The trait a SLAM plugin implements, and what it returns.

use abi_stable::StableAbi;
use serde::{Deserialize, Serialize};

use crate::messages::{Gnss, Imu, LaserScan, PointCloud, Pose, RgbdFrame, WheelOdometry};
use crate::rig::{Rig, SensorKind};

/// An error of a plugin, shown to the user as one line.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("{0}")]
pub struct PluginError(pub String);

impl PluginError {
    pub fn new(message: impl Into<String>) -> Self {
        Self(message.into())
    }
}

/// Whether the system estimates while the data arrives or only at the end.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "snake_case")]
pub enum Mode {
    #[default]
    Online,
    Offline,
}

/// What a plugin needs from the host, asked before it is created.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize, Default)]
pub struct Requirements {
    /// Sensor kinds the host must stream to it; others are not simulated for it.
    pub sensors: Vec<SensorKind>,
    pub mode: Mode,
    /// Whether the system can be started from a map it saved earlier and localise in it
    /// ([`SlamSystem::localize`]); revision 4. Absent (an older plugin): it cannot.
    #[serde(default, skip_serializing_if = "std::ops::Not::not")]
    pub can_localize: bool,
}

impl Requirements {
    pub fn online(sensors: &[SensorKind]) -> Self {
        Self {
            sensors: sensors.to_vec(),
            mode: Mode::Online,
            can_localize: false,
        }
    }

    /// These requirements, saying the system can localise in a saved map.
    pub fn localizing(mut self) -> Self {
        self.can_localize = true;
        self
    }
}

/// What a system believes of the pose it just returned (revision 4): localised in its map,
/// or still searching for where it is. A mapping run's poses are all
/// [`PoseStatus::Localized`] (the map is the system's own).
#[repr(u8)]
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default, Serialize, Deserialize, StableAbi)]
#[serde(rename_all = "snake_case")]
pub enum PoseStatus {
    #[default]
    Localized = 0,
    Searching = 1,
}

impl PoseStatus {
    /// The status's name as it crosses the Python door and is written in `status.csv`.
    pub fn name(self) -> &'static str {
        match self {
            Self::Localized => "localized",
            Self::Searching => "searching",
        }
    }

    /// The status called `name` (`localized` or `searching`).
    pub fn from_name(name: &str) -> Result<Self, PluginError> {
        match name {
            "localized" => Ok(Self::Localized),
            "searching" => Ok(Self::Searching),
            other => Err(PluginError(format!(
                "unknown pose status {other:?} (known: localized, searching)"
            ))),
        }
    }
}

/// A map a system saved at [`SlamSystem::finish`] (revision 4): opaque bytes in a format
/// the plugin names and versions. The host writes it as the run folder's `map.bin`, behind
/// a header naming the plugin, the format and a checksum, and hands the same bytes back to
/// [`SlamSystem::localize`].
#[derive(Debug, Clone, PartialEq, Eq, Default)]
pub struct SavedMap {
    /// The format's name, e.g. `"rtabmap-locations"`.
    pub format: String,
    /// The format's version: a plugin refuses bytes of a version it cannot read.
    pub version: u32,
    pub bytes: Vec<u8>,
}

/// A guess of where the robot starts in the map, with its uncertainty (revision 4). Without
/// one the start is unknown: global localisation.
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, StableAbi)]
pub struct InitialGuess {
    /// The guessed pose `map_from_base` (its stamp is the run's first instant, 0).
    pub map_from_base: Pose,
    /// Standard deviation of the position in x and in y (m).
    pub sigma_xy_m: f64,
    /// Standard deviation of the heading (rad).
    pub sigma_yaw_rad: f64,
}

/// What a system starting in localisation mode gets (revision 4).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MapStart<'a> {
    /// The bytes of the saved map: what this plugin returned as [`SavedMap::bytes`], or for
    /// [`GRID_MAP_FORMAT`] an occupancy grid the host read ([`OccupancyGrid::from_map_bytes`]).
    pub map: &'a [u8],
    pub format: &'a str,
    pub format_version: u32,
    pub initial_guess: Option<InitialGuess>,
}

/// The format of a map the host builds itself from an occupancy grid (a mapping run's
/// `grid.pgm` or the world's surveyed grid), for systems that localise in a 2D grid
/// (`amcl`): [`OccupancyGrid::to_map_bytes`].
pub const GRID_MAP_FORMAT: &str = "vinebench-grid";
/// The version of [`GRID_MAP_FORMAT`].
pub const GRID_MAP_VERSION: u32 = 1;

/// What kind of thing an [`Event`] is: the one registry of event kinds, for all three doors
/// (the C header's `events_toml` and the Python bridge's `finish()` take the same names,
/// [`EventKind::name`]; `docs/plugin-contract.md` lists them).
///
/// Open to additions: a later plugin-api may append kinds (the enum is `non_exhaustive`,
/// and events cross every door as their names), so a plugin built before a kind existed
/// keeps loading and never sends it. A name the host does not know fails the run with a
/// line naming it and the known ones, so a misspelt kind is not silently dropped.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
#[non_exhaustive]
pub enum EventKind {
    LoopClosureAccepted,
    LoopClosureRejected,
    TrackingLost,
    TrackingRecovered,
    GnssRejected,
}

impl EventKind {
    /// Every kind this plugin-api knows, in the order they were added.
    pub const ALL: [EventKind; 5] = [
        Self::LoopClosureAccepted,
        Self::LoopClosureRejected,
        Self::TrackingLost,
        Self::TrackingRecovered,
        Self::GnssRejected,
    ];

    /// The kind's name as it crosses the doors (`loop_closure_accepted`, ...).
    pub fn name(self) -> &'static str {
        match self {
            Self::LoopClosureAccepted => "loop_closure_accepted",
            Self::LoopClosureRejected => "loop_closure_rejected",
            Self::TrackingLost => "tracking_lost",
            Self::TrackingRecovered => "tracking_recovered",
            Self::GnssRejected => "gnss_rejected",
        }
    }

    /// What the kind means, one line (the contract table in `docs/plugin-contract.md`).
    pub fn description(self) -> &'static str {
        match self {
            Self::LoopClosureAccepted => {
                "a loop closure (or map merge) the system accepted into its map; judged against ground truth"
            }
            Self::LoopClosureRejected => {
                "a loop closure candidate the system checked and refused; counted, not judged"
            }
            Self::TrackingLost => "the system lost track (no pose until it recovers)",
            Self::TrackingRecovered => "the system tracks again after being lost",
            Self::GnssRejected => {
                "a GNSS fix the system refused (no fix, not finite, a bad covariance, or outside its gate)"
            }
        }
    }

    /// The kind called `name`; an error naming the known kinds otherwise.
    pub fn from_name(name: &str) -> Result<Self, PluginError> {
        Self::ALL
            .into_iter()
            .find(|k| k.name() == name)
            .ok_or_else(|| {
                let known: Vec<&str> = Self::ALL.iter().map(|k| k.name()).collect();
                PluginError(format!(
                    "unknown event kind {name:?} (known: {})",
                    known.join(", ")
                ))
            })
    }

    /// Whether this is a loop closure, accepted or rejected.
    pub fn is_loop_closure(&self) -> bool {
        matches!(self, Self::LoopClosureAccepted | Self::LoopClosureRejected)
    }
}

/// Something that happened during a run, for the report.
///
/// Build one with [`Event::new`] or, for a loop closure, [`Event::loop_closure`], which
/// also records the two stamps it joins: the host then judges every accepted loop against
/// ground truth (true when the two base poses are within 1 m of each other).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Event {
    pub stamp_ns: i64,
    pub kind: EventKind,
    /// Free text, e.g. which keyframes a loop closure joined and why it was rejected.
    pub detail: String,
    /// A loop closure's two base-pose stamps, `[current, matched]`: the newer keyframe or
    /// location and the older one it was joined to. `None` for other events, and from
    /// plugins built before the field existed (their loops are counted, not judged).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub loop_stamps_ns: Option<[i64; 2]>,
    /// A loop closure's measured relative pose `matched_from_current` between the two base
    /// poses of `loop_stamps_ns`, as `[x, y, z, qx, qy, qz, qw]` (metres, unit quaternion).
    /// With it the host judges the loop by whether this measurement agrees with ground
    /// truth, so a loop between two places several metres apart (scan matching across
    /// a lane) can be true and an aliased one false; without it, by distance alone.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub loop_relative_pose: Option<[f64; 7]>,
    /// A loop closure's matched keypoints between the colour frames at its two stamps, one
    /// `[u_current, v_current, u_matched, v_matched]` per match (pixels, column then row,
    /// (0, 0) the centre of the top-left pixel, as OpenCV has it). The report draws them
    /// over the two frames. Optional, since revision 3.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub loop_matches: Option<Vec<[f32; 4]>>,
}

impl Event {
    /// An event without loop stamps.
    pub fn new(stamp_ns: i64, kind: EventKind, detail: impl Into<String>) -> Self {
        Self {
            stamp_ns,
            kind,
            detail: detail.into(),
            loop_stamps_ns: None,
            loop_relative_pose: None,
            loop_matches: None,
        }
    }

    /// A loop closure of `kind` ([`EventKind::LoopClosureAccepted`] or
    /// [`EventKind::LoopClosureRejected`]) at `stamp_ns`, joining the base pose at
    /// `current_ns` to the older one at `matched_ns`.
    pub fn loop_closure(
        stamp_ns: i64,
        kind: EventKind,
        [current_ns, matched_ns]: [i64; 2],
        detail: impl Into<String>,
    ) -> Self {
        debug_assert!(kind.is_loop_closure(), "{kind:?} is not a loop closure");
        Self {
            loop_stamps_ns: Some([current_ns, matched_ns]),
            ..Self::new(stamp_ns, kind, detail)
        }
    }

    /// This loop closure with its measured relative pose `matched_from_current` between the
    /// base poses at its two stamps.
    pub fn with_relative_pose(mut self, matched_from_current: &nalgebra::Isometry3<f64>) -> Self {
        let t = matched_from_current.translation.vector;
        let q = matched_from_current.rotation.coords;
        self.loop_relative_pose = Some([t.x, t.y, t.z, q.x, q.y, q.z, q.w]);
        self
    }

    /// This loop closure with the keypoints it matched, `[u_current, v_current, u_matched,
    /// v_matched]` in pixels of the colour frames at its two stamps.
    pub fn with_matches(mut self, matches: Vec<[f32; 4]>) -> Self {
        self.loop_matches = Some(matches);
        self
    }

    /// The matched keypoints, if given and every coordinate finite.
    pub fn matches(&self) -> Option<&[[f32; 4]]> {
        self.loop_matches
            .as_deref()
            .filter(|m| m.iter().flatten().all(|v| v.is_finite()))
    }

    /// The measured relative pose `matched_from_current`, if given and valid.
    pub fn relative_pose(&self) -> Option<nalgebra::Isometry3<f64>> {
        let [x, y, z, qx, qy, qz, qw] = self.loop_relative_pose?;
        let q = nalgebra::Quaternion::new(qw, qx, qy, qz);
        let norm = q.norm();
        if !(norm.is_finite()
            && (norm - 1.0).abs() < 1e-6
            && [x, y, z].iter().all(|v| v.is_finite()))
        {
            return None;
        }
        Some(nalgebra::Isometry3::from_parts(
            nalgebra::Translation3::new(x, y, z),
            nalgebra::UnitQuaternion::new_unchecked(q),
        ))
    }
}

/// A 2D occupancy grid in the ROS map_server convention: cells row-major from the origin
/// corner, values 0 (free) to 100 (occupied), -1 unknown.
#[derive(Debug, Clone, PartialEq)]
pub struct OccupancyGrid {
    pub resolution_m: f64,
    /// World position of cell (0, 0)'s corner and the grid's yaw: [x, y, yaw].
    pub origin: [f64; 3],
    pub width: u32,
    pub height: u32,
    pub cells: Vec<i8>,
}

impl OccupancyGrid {
    /// The grid as [`GRID_MAP_FORMAT`] bytes: little-endian `resolution_m` (f64), `origin`
    /// (3 x f64), `width`, `height` (u32), then the cells (i8, row-major).
    pub fn to_map_bytes(&self) -> Vec<u8> {
        let mut out = Vec::with_capacity(40 + self.cells.len());
        out.extend_from_slice(&self.resolution_m.to_le_bytes());
        for v in self.origin {
            out.extend_from_slice(&v.to_le_bytes());
        }
        out.extend_from_slice(&self.width.to_le_bytes());
        out.extend_from_slice(&self.height.to_le_bytes());
        out.extend(self.cells.iter().map(|&c| c as u8));
        out
    }

    /// A grid from [`OccupancyGrid::to_map_bytes`]; an error says what is wrong.
    pub fn from_map_bytes(bytes: &[u8]) -> Result<Self, PluginError> {
        let bad = |why: &str| PluginError(format!("not a {GRID_MAP_FORMAT} map: {why}"));
        if bytes.len() < 40 {
            return Err(bad("shorter than its 40-byte head"));
        }
        let f = |i: usize| f64::from_le_bytes(bytes[i..i + 8].try_into().expect("8 bytes"));
        let u = |i: usize| u32::from_le_bytes(bytes[i..i + 4].try_into().expect("4 bytes"));
        let (resolution_m, origin, width, height) = (f(0), [f(8), f(16), f(24)], u(32), u(36));
        if !(resolution_m.is_finite() && resolution_m > 0.0)
            || origin.iter().any(|v| !v.is_finite())
        {
            return Err(bad(
                "its resolution is not positive or its origin not finite",
            ));
        }
        let n = width as usize * height as usize;
        if bytes.len() - 40 != n {
            return Err(bad(&format!(
                "{width} x {height} cells, but {} bytes of cells",
                bytes.len() - 40
            )));
        }
        let cells: Vec<i8> = bytes[40..].iter().map(|&b| b as i8).collect();
        if cells.iter().any(|&c| !(-1..=100).contains(&c)) {
            return Err(bad("a cell outside -1 ..= 100"));
        }
        Ok(Self {
            resolution_m,
            origin,
            width,
            height,
            cells,
        })
    }
}

/// What a plugin returns when the data is over.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct SlamOutput {
    /// The final (optimised) trajectory of the base, `map_from_base`.
    pub trajectory: Vec<Pose>,
    /// Map points in the map frame.
    pub map: Option<Vec<[f32; 3]>>,
    pub grid: Option<OccupancyGrid>,
    pub events: Vec<Event>,
    /// The map to localise in later (revision 4): written as the run folder's `map.bin`.
    pub saved_map: Option<SavedMap>,
}

/// A SLAM system as a plugin author writes it.
///
/// The same contract reaches C (`include/vinebench_plugin.h`) and Python (the bridge's
/// `vinebench_plugin.SlamSystem`): `docs/plugin-contract.md` is its one table, with every
/// message field as each language sees it, the event kinds, the version policy and what a
/// door cannot have. `vinebench check-plugin` checks a plugin against it.
///
/// Lifecycle, in this order:
/// 1. [`SlamSystem::requirements`] (or [`SlamSystem::requirements_for`] with the parameters)
///    — asked before anything else, to decide which sensors to simulate and stream;
/// 2. [`SlamSystem::new`] — with the plugin's parameter table (the TOML the user wrote for
///    it, verbatim) and the sensor rig;
/// 3. the message callbacks, in timestamp order of availability (a lidar sweep arrives at its
///    end, stamped at its start). Each may return a pose estimate `map_from_base` at some
///    stamp: the host records these as the online trajectory. The defaults ignore the
///    message;
/// 4. [`SlamSystem::finish`] — once, after the last message: the final trajectory, optional
///    map and grid, events and a [`SavedMap`] to localise in later.
///
/// In localisation mode (revision 4) [`SlamSystem::localize`] replaces `new`, and after each
/// pose it returns the host asks [`SlamSystem::status`].
///
/// A panic in any of them is caught inside the plugin and reported as an error of this run.
pub trait SlamSystem: Sized + Send + 'static {
    /// Short name, e.g. `"lio"`; the host finds plugins by it.
    const NAME: &'static str;
    /// The plugin's own version.
    const VERSION: &'static str;

    fn requirements() -> Requirements;

    /// The requirements for this parameter table (the TOML [`SlamSystem::new`] will get):
    /// asked instead of [`SlamSystem::requirements`] when the host knows the parameters, for
    /// a plugin whose sensors depend on them (a bridge hosting a system named in its
    /// parameters). The default ignores them.
    fn requirements_for(config_toml: &str) -> Result<Requirements, PluginError> {
        let _ = config_toml;
        Ok(Self::requirements())
    }

    fn new(config_toml: &str, rig: &Rig) -> Result<Self, PluginError>;

    /// Creates the system in localisation mode, from a map saved earlier (revision 4): its
    /// own [`SavedMap`]'s bytes, or for a plugin that localises in a 2D grid the host's
    /// [`GRID_MAP_FORMAT`]. Answer every message as usual, with poses in the saved map's
    /// frame, and say with [`SlamSystem::status`] whether each is localised. Say
    /// `can_localize` in the requirements when this is implemented; refuse a format or
    /// version you cannot read with an error saying so. The default refuses.
    fn localize(config_toml: &str, rig: &Rig, start: &MapStart<'_>) -> Result<Self, PluginError> {
        let _ = (config_toml, rig, start);
        Err(PluginError(format!(
            "{} cannot localise in a saved map",
            Self::NAME
        )))
    }

    /// Whether the pose just returned is localised in the map or the system still searches
    /// (revision 4); asked after every pose returned. The default: localised.
    fn status(&self) -> PoseStatus {
        PoseStatus::Localized
    }

    fn on_imu(&mut self, imu: &Imu) -> Result<Option<Pose>, PluginError> {
        let _ = imu;
        Ok(None)
    }

    fn on_wheel_odometry(&mut self, odom: &WheelOdometry) -> Result<Option<Pose>, PluginError> {
        let _ = odom;
        Ok(None)
    }

    fn on_point_cloud(&mut self, cloud: &PointCloud<'_>) -> Result<Option<Pose>, PluginError> {
        let _ = cloud;
        Ok(None)
    }

    fn on_laser_scan(&mut self, scan: &LaserScan<'_>) -> Result<Option<Pose>, PluginError> {
        let _ = scan;
        Ok(None)
    }

    fn on_rgbd(&mut self, frame: &RgbdFrame<'_>) -> Result<Option<Pose>, PluginError> {
        let _ = frame;
        Ok(None)
    }

    /// A GNSS epoch (revision 5), for a system that asks for [`SensorKind::Gnss`]. Read it
    /// through [`Gnss::problem`], [`Gnss::position`] and [`Gnss::covariance`]: a fix may be
    /// absent, and a broken receiver may send NaN or a zero covariance.
    fn on_gnss(&mut self, gnss: &Gnss) -> Result<Option<Pose>, PluginError> {
        let _ = gnss;
        Ok(None)
    }

    fn finish(&mut self) -> Result<SlamOutput, PluginError>;
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The registry is the one list of kinds: serde's names are `name()`, `from_name` is its
    /// inverse and refuses others naming the known ones, and the header, the contract page
    /// and the Python base class name every kind and the same revision.
    #[test]
    fn every_door_names_the_registry_s_kinds() {
        for kind in EventKind::ALL {
            let serde: String = toml::Value::try_from(kind)
                .expect("serialises")
                .as_str()
                .expect("a string")
                .to_owned();
            assert_eq!(serde, kind.name());
            assert_eq!(EventKind::from_name(kind.name()), Ok(kind));
            assert!(!kind.description().is_empty());
        }
        let unknown = EventKind::from_name("loop_closure").expect_err("unknown");
        assert!(
            unknown.0.contains("\"loop_closure\"") && unknown.0.contains("tracking_lost"),
            "{unknown}"
        );
        let root = concat!(env!("CARGO_MANIFEST_DIR"), "/..");
        let read = |path: &str| {
            std::fs::read_to_string(format!("{root}/{path}"))
                .unwrap_or_else(|e| panic!("{path}: {e}"))
        };
        let header = read("plugin-api/include/vinebench_plugin.h");
        let contract = read("docs/plugin-contract.md");
        for kind in EventKind::ALL {
            assert!(
                header.contains(&format!("\"{}\"", kind.name())),
                "the header lacks {}",
                kind.name()
            );
            assert!(
                contract.contains(&format!("| `{}` | {} |", kind.name(), kind.description())),
                "docs/plugin-contract.md's table lacks {} as the registry describes it",
                kind.name()
            );
        }
        let python = read("plugins/python-bridge/python/vinebench_plugin.py");
        assert!(
            python.contains(&format!("API_REVISION = {}", crate::ABI_REVISION)),
            "vinebench_plugin.py's API_REVISION is not {}",
            crate::ABI_REVISION
        );
        assert!(header.contains(&format!("#define VB_ABI_REVISION {}u", crate::ABI_REVISION)));
    }
}
