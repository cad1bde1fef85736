//! Routes: the paths of the paper's scenarios, built from the vineyard's geometry, or the
//! user's own waypoints.

use nalgebra::Point2;

use crate::config::{RouteSpec, VineyardConfig};
use crate::error::SimError;

/// Spacing of the points that describe a path.
const STEP_M: f64 = 0.05;

/// One part of a route.
#[derive(Debug, Clone, PartialEq)]
pub enum Leg {
    /// Drive along a densely sampled polyline without stopping.
    Drive(Vec<Point2<f64>>),
    /// Stop and turn on the spot to a heading.
    Rotate { yaw: f64 },
}

/// A route: where the robot starts, facing which way, and its legs.
#[derive(Debug, Clone, PartialEq)]
pub struct Route {
    pub name: String,
    pub start: Point2<f64>,
    pub start_yaw: f64,
    pub legs: Vec<Leg>,
}

impl Route {
    /// Path length of the drive legs (turns on the spot add none).
    pub fn length(&self) -> f64 {
        self.legs
            .iter()
            .map(|leg| match leg {
                Leg::Drive(points) => polyline_length(points),
                Leg::Rotate { .. } => 0.0,
            })
            .sum()
    }

    /// Builds the route `spec` named `name` in the vineyard `v`.
    pub fn build(name: &str, spec: &RouteSpec, v: &VineyardConfig) -> Result<Self, SimError> {
        let err = |message: String| SimError::Route {
            name: name.to_owned(),
            message,
        };
        let check_lane = |lane: usize| {
            if lane < v.lanes() {
                Ok(v.lane_y(lane))
            } else {
                Err(err(format!(
                    "lane {lane} does not exist: the vineyard has {} lanes",
                    v.lanes()
                )))
            }
        };
        let end = v.row_length_m;
        let legs = match *spec {
            RouteSpec::Straight {
                lane,
                start_x_m,
                length_m,
            } => {
                let y = check_lane(lane)?;
                vec![Leg::Drive(segment(
                    [start_x_m, y],
                    [start_x_m + length_m, y],
                ))]
            }
            RouteSpec::SameLane {
                lane,
                overshoot_m: a,
            } => {
                let y = check_lane(lane)?;
                vec![
                    Leg::Drive(segment([-a, y], [end + a, y])),
                    Leg::Rotate {
                        yaw: std::f64::consts::PI,
                    },
                    Leg::Drive(segment([end + a, y], [-a, y])),
                ]
            }
            RouteSpec::AdjacentLane { lane, overshoot_m } => {
                check_lane(lane + 1)?;
                vec![Leg::Drive(serpentine(v, &[lane, lane + 1], overshoot_m))]
            }
            RouteSpec::Serpentine {
                first_lane,
                lanes,
                overshoot_m,
            } => {
                check_lane(first_lane + lanes - 1)?;
                let lanes: Vec<usize> = (first_lane..first_lane + lanes).collect();
                vec![Leg::Drive(serpentine(v, &lanes, overshoot_m))]
            }
            RouteSpec::LaneSequence {
                ref lanes,
                overshoot_m,
            } => {
                for &lane in lanes {
                    check_lane(lane)?;
                }
                vec![Leg::Drive(serpentine(v, lanes, overshoot_m))]
            }
            RouteSpec::Goals {
                start,
                ref goals,
                send_goals_swap_zw,
            } => {
                let heading = |yaw_deg: f64| {
                    if send_goals_swap_zw {
                        (180.0 - yaw_deg).to_radians()
                    } else {
                        yaw_deg.to_radians()
                    }
                };
                let start_point = Point2::new(start[0], start[1]);
                return Ok(Self {
                    name: name.to_owned(),
                    start: start_point,
                    start_yaw: start[2].to_radians(),
                    legs: goal_legs(start_point, start[2].to_radians(), goals, heading),
                });
            }
            RouteSpec::Waypoints { ref points } => {
                let mut path = vec![Point2::from(points[0])];
                for pair in points.windows(2) {
                    path.extend(segment(pair[0], pair[1]).into_iter().skip(1));
                }
                vec![Leg::Drive(path)]
            }
        };
        let first = match &legs[0] {
            Leg::Drive(points) => points,
            Leg::Rotate { .. } => unreachable!("every route starts by driving"),
        };
        let (start, next) = (first[0], first[1]);
        if (next - start).norm() < 1e-9 {
            return Err(err("the first two points coincide".into()));
        }
        Ok(Self {
            name: name.to_owned(),
            start,
            start_yaw: (next.y - start.y).atan2(next.x - start.x),
            legs,
        })
    }
}

/// Smallest turn on the spot worth a leg of its own (1°).
const MIN_TURN_RAD: f64 = std::f64::consts::PI / 180.0;

/// The legs of a goal sequence: turn towards the next goal, drive straight to it, turn to
/// its heading (each turn only where it exceeds [`MIN_TURN_RAD`]).
fn goal_legs(
    start: Point2<f64>,
    start_yaw: f64,
    goals: &[[f64; 3]],
    heading: impl Fn(f64) -> f64,
) -> Vec<Leg> {
    let off = |a: f64, b: f64| super::controller::wrap(a - b);
    let (mut at, mut yaw) = (start, start_yaw);
    let mut legs = Vec::new();
    for goal in goals {
        let to = Point2::new(goal[0], goal[1]);
        let d = to - at;
        if d.norm() > 1e-6 {
            let towards = d.y.atan2(d.x);
            if off(towards, yaw).abs() > MIN_TURN_RAD {
                legs.push(Leg::Rotate { yaw: towards });
            }
            legs.push(Leg::Drive(segment([at.x, at.y], [to.x, to.y])));
            (at, yaw) = (to, towards);
        }
        let wanted = heading(goal[2]);
        if off(wanted, yaw).abs() > MIN_TURN_RAD {
            legs.push(Leg::Rotate { yaw: wanted });
            yaw = wanted;
        }
    }
    legs
}

fn polyline_length(points: &[Point2<f64>]) -> f64 {
    points.windows(2).map(|w| (w[1] - w[0]).norm()).sum()
}

/// Points from `a` to `b` (both included) about `STEP_M` apart.
fn segment(a: [f64; 2], b: [f64; 2]) -> Vec<Point2<f64>> {
    let (a, b) = (Point2::from(a), Point2::from(b));
    let n = ((b - a).norm() / STEP_M).ceil().max(1.0) as usize;
    (0..=n)
        .map(|i| a + (b - a) * (i as f64 / n as f64))
        .collect()
}

/// Half a circle of radius `r` about `centre` from angle `from` through `sweep` radians.
fn arc(centre: Point2<f64>, r: f64, from: f64, sweep: f64) -> Vec<Point2<f64>> {
    let n = (r * sweep.abs() / STEP_M).ceil().max(2.0) as usize;
    (0..=n)
        .map(|i| {
            let a = from + sweep * i as f64 / n as f64;
            centre + nalgebra::Vector2::new(a.cos(), a.sin()) * r
        })
        .collect()
}

/// Along `lanes` in order (two in a row differ), the first along +x and then alternating,
/// from `overshoot` before the rows to `overshoot` past them, joined by U-turns beyond the
/// rows: half circles of radius half the distance between the two lanes.
fn serpentine(v: &VineyardConfig, lanes: &[usize], overshoot: f64) -> Vec<Point2<f64>> {
    use std::f64::consts::{FRAC_PI_2, PI};
    let (lo, hi) = (-overshoot, v.row_length_m + overshoot);
    let mut path: Vec<Point2<f64>> = Vec::new();
    for (k, &lane) in lanes.iter().enumerate() {
        let y = v.lane_y(lane);
        let forward = k % 2 == 0;
        let (a, b) = if forward { (lo, hi) } else { (hi, lo) };
        let skip = usize::from(!path.is_empty());
        path.extend(segment([a, y], [b, y]).into_iter().skip(skip));
        if let Some(&next) = lanes.get(k + 1) {
            let centre = Point2::new(b, y + 0.5 * (v.lane_y(next) - y));
            let r = 0.5 * v.row_spacing_m * next.abs_diff(lane) as f64;
            // From the side of the centre the robot is on, round the outside of the rows:
            // counter-clockwise when going east to a higher lane or west to a lower one.
            let up = next > lane;
            let from = if up { -FRAC_PI_2 } else { FRAC_PI_2 };
            let sweep = if forward == up { PI } else { -PI };
            path.extend(arc(centre, r, from, sweep).into_iter().skip(1));
        }
    }
    path
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn builtin_routes_have_their_nominal_lengths() {
        let v = VineyardConfig::default();
        // The paper's S0-S3; s4: three lanes of 18 + 2 × 3.47 m and two U-turns of 1.5 m.
        let s4 = 3.0 * (18.0 + 2.0 * 3.47) + 2.0 * std::f64::consts::PI * 1.5;
        for (name, expected) in [
            ("s0", 25.0),
            ("s1", 48.6),
            ("s2", 54.6),
            ("s3", 101.2),
            ("s4", s4),
        ] {
            let spec = &RouteSpec::builtin_scenarios()[name];
            let len = Route::build(name, spec, &v).expect("route builds").length();
            assert!(
                (len - expected).abs() / expected < 0.005,
                "{name}: nominal path {len:.2} m, paper {expected} m"
            );
        }
    }

    #[test]
    fn missing_lane_is_an_error_naming_the_route() {
        let v = VineyardConfig::default();
        let spec = RouteSpec::SameLane {
            lane: 8,
            overshoot_m: 1.0,
        };
        let e = Route::build("mine", &spec, &v).expect_err("lane 8 of 8 lanes does not exist");
        assert!(
            e.to_string().contains("mine") && e.to_string().contains("lane 8"),
            "{e}"
        );
    }

    /// The points of a drive leg whose heading (to the next point) is within 1° of `yaw`
    /// and lie on `y`, as (min x, max x).
    fn driven_along(points: &[Point2<f64>], y: f64, yaw: f64) -> Option<(f64, f64)> {
        let xs: Vec<f64> = points
            .windows(2)
            .filter(|w| {
                let d = w[1] - w[0];
                let off = (d.y.atan2(d.x) - yaw + std::f64::consts::PI)
                    .rem_euclid(std::f64::consts::TAU)
                    - std::f64::consts::PI;
                (w[0].y - y).abs() < 1e-9 && off.abs() < 1f64.to_radians()
            })
            .map(|w| w[0].x)
            .collect();
        let lo = xs.iter().copied().fold(f64::INFINITY, f64::min);
        let hi = xs.iter().copied().fold(f64::NEG_INFINITY, f64::max);
        (!xs.is_empty()).then_some((lo, hi))
    }

    #[test]
    fn a_lane_sequence_turns_round_the_row_ends_into_each_lane() {
        let v = VineyardConfig::default();
        // Down, up by two lanes, and down by one: every U-turn stays beyond the rows.
        let spec = RouteSpec::LaneSequence {
            lanes: vec![5, 3, 4],
            overshoot_m: 2.0,
        };
        let route = Route::build("mine", &spec, &v).expect("builds");
        let [Leg::Drive(points)] = route.legs.as_slice() else {
            panic!("one drive leg: {:?}", route.legs.len());
        };
        let (east, west) = (0.0, std::f64::consts::PI);
        for (lane, yaw) in [(5, east), (3, west), (4, east)] {
            let (lo, hi) = driven_along(points, v.lane_y(lane), yaw)
                .unwrap_or_else(|| panic!("lane {lane} is driven at yaw {yaw}"));
            assert!(
                lo < -1.9 && hi > v.row_length_m + 1.9,
                "lane {lane}: {lo}..{hi}"
            );
        }
        assert!(
            points.iter().all(
                |p| p.x <= -2.0 + 1e-9 || p.x >= v.row_length_m + 2.0 - 1e-9 || {
                    [3, 4, 5].iter().any(|&l| (p.y - v.lane_y(l)).abs() < 1e-9)
                }
            ),
            "between the row ends the path keeps to the lanes"
        );
        let steps: Vec<f64> = points.windows(2).map(|w| (w[1] - w[0]).norm()).collect();
        assert!(
            steps.iter().all(|&d| d > 1e-6 && d <= STEP_M + 1e-9),
            "dense and without repeated points: max step {:?}",
            steps.iter().copied().fold(0.0, f64::max)
        );
        let expected = 3.0 * (18.0 + 4.0) + std::f64::consts::PI * (3.0 + 1.5);
        assert!(
            (route.length() - expected).abs() < 0.01,
            "{}",
            route.length()
        );
    }
}
