//! The routes through the vineyard: the paper's scenarios by kind (straight, same lane,
//! adjacent lane, serpentine) or any list of waypoints.

use super::*;

/// A route through the vineyard. Lanes are numbered from 0 (between rows 0 and 1).
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
#[serde(tag = "kind", rename_all = "snake_case", deny_unknown_fields)]
pub enum RouteSpec {
    /// Straight along a lane, starting `start_x_m` along the row axis.
    Straight {
        lane: usize,
        start_x_m: f64,
        length_m: f64,
    },
    /// Down a lane, turn on the spot in the headland, back up the same lane.
    SameLane { lane: usize, overshoot_m: f64 },
    /// Down a lane, a U-turn in the headland, back up the next lane.
    AdjacentLane { lane: usize, overshoot_m: f64 },
    /// Up and down `lanes` consecutive lanes joined by U-turns.
    Serpentine {
        first_lane: usize,
        lanes: usize,
        overshoot_m: f64,
    },
    /// The given lanes in order, joined by U-turns in the headlands: the first driven along
    /// +x, the next the other way, and so on; two in a row must differ. `[3, 4, 3]` drives
    /// lane 3 twice in the same direction.
    LaneSequence { lanes: Vec<usize>, overshoot_m: f64 },
    /// The user's own path: at least two (x, y) points in the world frame, driven in order.
    Waypoints { points: Vec<[f64; 2]> },
    /// Navigation goals driven one after the other as the paper's robot drove them with
    /// `move_base`: from `start` (`[x, y, yaw_deg]`, the robot's spawn pose), for each goal
    /// `[x, y, yaw_deg]` turn on the spot towards it, drive straight to it, and turn on the
    /// spot to its heading. Source: `bacchus_move_base/config/goals/scenario_*.txt`, sent by
    /// `bacchus_move_base/scripts/send_goals.py` (LCAS/bacchus_lcas, branch `liosam`).
    Goals {
        start: [f64; 3],
        goals: Vec<[f64; 3]>,
        /// `send_goals.py` writes the goal quaternion's z into w and w into z, which turns a
        /// written yaw ψ into the heading 180° − ψ; `true` drives the headings the paper's
        /// robot actually took from the yaws as written in its goal files.
        #[serde(default)]
        send_goals_swap_zw: bool,
    },
}

impl RouteSpec {
    /// The built-in scenarios: the paper's S0-S3 and our s4, lane 3 eastwards, a U-turn
    /// into lane 4 westwards, a U-turn back into lane 3 eastwards (S2 and back into its
    /// first lane; 84.2 m in the default world), so places are seen again from the same
    /// side.
    pub fn builtin_scenarios() -> BTreeMap<String, RouteSpec> {
        let mut scenarios = Self::paper_scenarios();
        scenarios.insert(
            "s4".to_owned(),
            RouteSpec::LaneSequence {
                lanes: vec![3, 4, 3],
                overshoot_m: 3.47,
            },
        );
        scenarios
    }

    /// The paper's scenarios S0-S3 (lengths 25, 48.6, 54.6, 101.2 m in the default world).
    pub fn paper_scenarios() -> BTreeMap<String, RouteSpec> {
        BTreeMap::from([
            (
                "s0".to_owned(),
                RouteSpec::Straight {
                    lane: 3,
                    start_x_m: -3.5,
                    length_m: 25.0,
                },
            ),
            (
                "s1".to_owned(),
                RouteSpec::SameLane {
                    lane: 3,
                    overshoot_m: 3.15,
                },
            ),
            (
                "s2".to_owned(),
                RouteSpec::AdjacentLane {
                    lane: 3,
                    overshoot_m: 3.47,
                },
            ),
            (
                "s3".to_owned(),
                RouteSpec::Serpentine {
                    first_lane: 2,
                    lanes: 4,
                    overshoot_m: 1.88,
                },
            ),
        ])
    }

    pub(super) fn validate(&self) -> Result<(), String> {
        match self {
            RouteSpec::Straight { length_m, .. } => positive("length_m", *length_m),
            RouteSpec::SameLane { overshoot_m, .. }
            | RouteSpec::AdjacentLane { overshoot_m, .. } => {
                non_negative("overshoot_m", *overshoot_m)
            }
            RouteSpec::Serpentine {
                lanes, overshoot_m, ..
            } => {
                if *lanes == 0 {
                    return Err("lanes = 0: need at least one lane".into());
                }
                non_negative("overshoot_m", *overshoot_m)
            }
            RouteSpec::LaneSequence { lanes, overshoot_m } => {
                if lanes.is_empty() {
                    return Err("lanes = []: need at least one lane".into());
                }
                if let Some(pair) = lanes.windows(2).find(|p| p[0] == p[1]) {
                    return Err(format!(
                        "lanes: lane {} twice in a row; a U-turn needs another lane",
                        pair[0]
                    ));
                }
                non_negative("overshoot_m", *overshoot_m)
            }
            RouteSpec::Goals { start, goals, .. } => {
                if goals.is_empty() {
                    Err("goals = []: need at least one goal".into())
                } else if start
                    .iter()
                    .chain(goals.iter().flatten())
                    .any(|v| !v.is_finite())
                {
                    Err("start and goals: every value must be finite".into())
                } else {
                    Ok(())
                }
            }
            RouteSpec::Waypoints { points } => {
                if points.len() < 2 {
                    Err(format!("points: {} given, need at least 2", points.len()))
                } else if points.iter().flatten().any(|v| !v.is_finite()) {
                    Err("points: every coordinate must be finite".into())
                } else {
                    Ok(())
                }
            }
        }
    }
}
