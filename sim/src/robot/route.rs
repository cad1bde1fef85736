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
        let half = 0.5 * v.row_spacing_m;
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
                vec![Leg::Drive(serpentine(v, lane, 2, overshoot_m, half))]
            }
            RouteSpec::Serpentine {
                first_lane,
                lanes,
                overshoot_m,
            } => {
                check_lane(first_lane + lanes - 1)?;
                vec![Leg::Drive(serpentine(
                    v,
                    first_lane,
                    lanes,
                    overshoot_m,
                    half,
                ))]
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

/// Up and down `lanes` lanes from `first`, joined by U-turns of radius `r` beyond the rows.
fn serpentine(
    v: &VineyardConfig,
    first: usize,
    lanes: usize,
    overshoot: f64,
    r: f64,
) -> Vec<Point2<f64>> {
    let (lo, hi) = (-overshoot, v.row_length_m + overshoot);
    let mut path: Vec<Point2<f64>> = Vec::new();
    for k in 0..lanes {
        let y = v.lane_y(first + k);
        let forward = k % 2 == 0;
        let (a, b) = if forward { (lo, hi) } else { (hi, lo) };
        let skip = usize::from(!path.is_empty());
        path.extend(segment([a, y], [b, y]).into_iter().skip(skip));
        if k + 1 < lanes {
            let centre = Point2::new(b, y + 0.5 * (v.lane_y(first + k + 1) - y));
            let half_pi = std::f64::consts::FRAC_PI_2;
            // Turn left at the far end (counter-clockwise), right at the near end.
            let (from, sweep) = if forward {
                (-half_pi, std::f64::consts::PI)
            } else {
                (-half_pi, -std::f64::consts::PI)
            };
            path.extend(
                arc(centre, r.min(0.5 * v.row_spacing_m), from, sweep)
                    .into_iter()
                    .skip(1),
            );
        }
    }
    path
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn paper_routes_have_the_papers_nominal_lengths() {
        let v = VineyardConfig::default();
        for (name, expected) in [("s0", 25.0), ("s1", 48.6), ("s2", 54.6), ("s3", 101.2)] {
            let spec = &RouteSpec::paper_scenarios()[name];
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
}
