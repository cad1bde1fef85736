//! The realism ladder: which sensor models a world runs under.
//!
//! A world file says `profile = "..."`; the profile's table (`configs/profiles/<name>.toml`,
//! embedded) lies under the file's own keys, which lie under the built-in defaults' gaps:
//!
//! ```text
//! built-in defaults  <-  the profile's keys  <-  the world file's keys  (<- a sweep's axes,
//!                                                                         which edit the file)
//! ```
//!
//! Tables merge key by key; a value or an array replaces. So a world file keeps what belongs
//! to the place and the robot (the block, the ground, the fence, the routes, where each
//! sensor sits, the sun) and a profile what belongs to the sensors' models (rates,
//! resolution, fields of view, noise), and `"profile" = ["ideal", "paper", "typical", "field"]` in a
//! sweep's `[axes]` crosses the ladder on any world. A key the world file states itself wins
//! over its profile: a world that should climb the ladder leaves the sensor models out.

use serde::{Deserialize, Serialize};

/// One rung of the ladder.
#[derive(
    Debug, Clone, Copy, Default, PartialEq, Eq, PartialOrd, Ord, Hash, Deserialize, Serialize,
)]
#[serde(rename_all = "lowercase")]
pub enum Profile {
    /// No noise on any sensor (the models' geometry kept: a lidar's columns still fire one
    /// after another as it spins).
    Ideal,
    /// The paper's Gazebo sensors (LCAS/bacchus_lcas, branch `liosam`): a 1 kHz IMU without
    /// noise that reports its orientation, the lidar's sweep at one instant with σ 8 mm, the
    /// Kinect's 70° depth beside its 84.1° colour camera.
    Paper,
    /// Today's sensors as datasheets state them (the default): a MEMS IMU's densities and
    /// biases, wheel scale and slip, per-column lidar timing, Kinect v2 depth noise.
    #[default]
    Typical,
    /// `typical` and what makes the field harder, one key per factor (being built: so far
    /// the lidar-IMU calibration's error; `configs/profiles/field.toml` lists the rest).
    Field,
}

impl Profile {
    pub const ALL: [Profile; 4] = [
        Profile::Ideal,
        Profile::Paper,
        Profile::Typical,
        Profile::Field,
    ];

    pub fn name(self) -> &'static str {
        match self {
            Profile::Ideal => "ideal",
            Profile::Paper => "paper",
            Profile::Typical => "typical",
            Profile::Field => "field",
        }
    }

    /// The profile's file, embedded: the keys it sets.
    pub fn toml(self) -> &'static str {
        match self {
            Profile::Ideal => include_str!("../../../configs/profiles/ideal.toml"),
            Profile::Paper => include_str!("../../../configs/profiles/paper.toml"),
            Profile::Typical => include_str!("../../../configs/profiles/typical.toml"),
            Profile::Field => include_str!("../../../configs/profiles/field.toml"),
        }
    }

    /// The profile's keys as a table (a profile file that does not parse is a build defect,
    /// caught by the tests).
    pub(super) fn table(self) -> toml::Table {
        self.toml()
            .parse()
            .unwrap_or_else(|e| panic!("configs/profiles/{}.toml: {e}", self.name()))
    }
}

/// Lays `over` on `base`: tables merge key by key, anything else replaces.
pub(super) fn overlay(base: &mut toml::Table, over: toml::Table) {
    for (key, value) in over {
        match (base.get_mut(&key), value) {
            (Some(toml::Value::Table(below)), toml::Value::Table(above)) => overlay(below, above),
            (_, value) => {
                base.insert(key, value);
            }
        }
    }
}
