//! The robot's path-following controller and planar kinematics: pure pursuit (Coulter 1992,
//! "Implementation of the Pure Pursuit Path Tracking Algorithm") on drive legs, a
//! proportional turn on the spot on rotate legs, and command filters that limit speed,
//! acceleration and jerk, so that velocity and acceleration are continuous.

use nalgebra::{Point2, Vector2};

use super::route::{Leg, Route};
use crate::config::RobotConfig;

/// Controller period.
pub const CONTROL_DT_S: f64 = 0.005;
/// Deceleration used to plan stops, below the limit so the jerk-limited filter can follow.
const PLAN_DECEL_FRACTION: f64 = 0.3;
/// Hard cap on simulated time, against a route that can never be finished.
const MAX_DURATION_S: f64 = 3600.0;

/// A planar state sample of the controller.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PlanarSample {
    pub t: f64,
    pub x: f64,
    pub y: f64,
    /// Unwrapped heading (continuous across ±π).
    pub yaw: f64,
}

/// A scalar with a rate limit on its first and second derivative that tracks a command.
#[derive(Debug, Clone, Copy, Default)]
struct Filtered {
    value: f64,
    rate: f64,
}

impl Filtered {
    fn track(&mut self, command: f64, max_rate: f64, max_jerk: f64, gain: f64, dt: f64) {
        let wanted = (gain * (command - self.value)).clamp(-max_rate, max_rate);
        self.rate += (wanted - self.rate).clamp(-max_jerk * dt, max_jerk * dt);
        self.value += self.rate * dt;
    }
}

/// The base's planar state and its filtered commands.
#[derive(Debug)]
struct Base {
    t: f64,
    pos: Point2<f64>,
    yaw: f64,
    v: Filtered,
    w: Filtered,
}

impl Base {
    fn sample(&self) -> PlanarSample {
        PlanarSample {
            t: self.t,
            x: self.pos.x,
            y: self.pos.y,
            yaw: self.yaw,
        }
    }

    /// Filters the commands and moves one control period (exact unicycle step with the
    /// period's constant rates); `None` past the time cap.
    fn step(
        &mut self,
        v_cmd: f64,
        w_cmd: f64,
        cfg: &RobotConfig,
        out: &mut Vec<PlanarSample>,
    ) -> Option<()> {
        let dt = CONTROL_DT_S;
        // The yaw-rate filter's jerk limit is the linear one per metre of track.
        let yaw_jerk = cfg.max_jerk_mps3 / cfg.wheel_y_m.max(0.1);
        self.v
            .track(v_cmd, cfg.max_accel_mps2, cfg.max_jerk_mps3, 3.0, dt);
        self.w
            .track(w_cmd, cfg.max_yaw_accel_rps2, yaw_jerk, 6.0, dt);
        let dyaw = self.w.value * dt;
        let mid = self.yaw + 0.5 * dyaw;
        self.pos += Vector2::new(mid.cos(), mid.sin()) * (self.v.value * dt);
        self.yaw += dyaw;
        self.t += dt;
        out.push(self.sample());
        (self.t <= MAX_DURATION_S).then_some(())
    }

    fn at_rest(&self) -> bool {
        [self.v.value, self.w.value, self.v.rate, self.w.rate]
            .iter()
            .all(|x| x.abs() <= 1e-6)
    }
}

/// Drives `route` and returns the planar state every [`CONTROL_DT_S`], standing still for
/// `still_s` before and after. `None` if the controller cannot finish within an hour.
pub fn drive(route: &Route, cfg: &RobotConfig) -> Option<Vec<PlanarSample>> {
    let mut base = Base {
        t: 0.0,
        pos: route.start,
        yaw: route.start_yaw,
        v: Filtered::default(),
        w: Filtered::default(),
    };
    let mut out = Vec::new();
    let steps_still = (cfg.still_s / CONTROL_DT_S).round() as usize;
    let stand_still = |base: &mut Base, out: &mut Vec<PlanarSample>| {
        for _ in 0..steps_still {
            out.push(base.sample());
            base.t += CONTROL_DT_S;
        }
    };
    stand_still(&mut base, &mut out);
    for leg in &route.legs {
        let mut follower = match leg {
            Leg::Drive(points) => Some(PathFollower::new(points)),
            Leg::Rotate { .. } => None,
        };
        loop {
            let (v_cmd, w_cmd, done) = match (leg, follower.as_mut()) {
                (Leg::Drive(_), Some(f)) => f.command(base.pos, base.yaw, base.v.value, cfg),
                (Leg::Rotate { yaw: target }, _) => {
                    let e = wrap(target - base.yaw);
                    let w_max = (2.0 * PLAN_DECEL_FRACTION * cfg.max_yaw_accel_rps2 * e.abs())
                        .sqrt()
                        .min(cfg.max_yaw_rate_rps);
                    (
                        0.0,
                        w_max * e.signum(),
                        e.abs() < 1e-3 && base.w.value.abs() < 0.02,
                    )
                }
                (Leg::Drive(_), None) => unreachable!("a drive leg always has a follower"),
            };
            if done {
                break;
            }
            base.step(v_cmd, w_cmd, cfg, &mut out)?;
        }
    }
    // Come to rest, then stand still.
    while !base.at_rest() {
        base.step(0.0, 0.0, cfg, &mut out)?;
    }
    base.t += CONTROL_DT_S;
    stand_still(&mut base, &mut out);
    Some(out)
}

/// `a` wrapped to [-π, π).
pub(super) fn wrap(a: f64) -> f64 {
    (a + std::f64::consts::PI).rem_euclid(std::f64::consts::TAU) - std::f64::consts::PI
}

/// Pure pursuit along a polyline with a speed profile that respects the yaw-rate limit on
/// curves and stops at the end.
#[derive(Debug)]
struct PathFollower<'a> {
    points: &'a [Point2<f64>],
    /// Arc length at each point.
    s: Vec<f64>,
    /// Index of the point closest to the robot, searched forward only.
    closest: usize,
}

impl<'a> PathFollower<'a> {
    fn new(points: &'a [Point2<f64>]) -> Self {
        let mut s = vec![0.0; points.len()];
        for i in 1..points.len() {
            s[i] = s[i - 1] + (points[i] - points[i - 1]).norm();
        }
        Self {
            points,
            s,
            closest: 0,
        }
    }

    fn total(&self) -> f64 {
        *self.s.last().expect("a path has points")
    }

    /// The point at arc length `s`, extrapolated along the last segment beyond the end.
    fn at(&self, s: f64) -> Point2<f64> {
        let n = self.points.len();
        if s >= self.total() {
            let dir = (self.points[n - 1] - self.points[n - 2]).normalize();
            return self.points[n - 1] + dir * (s - self.total());
        }
        let i = self.s.partition_point(|&si| si <= s).clamp(1, n - 1);
        let f = (s - self.s[i - 1]) / (self.s[i] - self.s[i - 1]).max(1e-12);
        self.points[i - 1] + (self.points[i] - self.points[i - 1]) * f
    }

    /// (speed command, yaw-rate command, finished).
    fn command(
        &mut self,
        pos: Point2<f64>,
        yaw: f64,
        v_now: f64,
        cfg: &RobotConfig,
    ) -> (f64, f64, bool) {
        // Advance the closest point within a short window ahead.
        let window = (self.closest + 200).min(self.points.len());
        let mut best = (self.points[self.closest] - pos).norm();
        for i in self.closest + 1..window {
            let d = (self.points[i] - pos).norm();
            if d < best {
                best = d;
                self.closest = i;
            }
        }
        let heading = Vector2::new(yaw.cos(), yaw.sin());
        // Progress along the path, refined by projecting onto the path's direction.
        let end = *self.points.last().expect("a path has points");
        let remaining = if self.closest + 1 >= self.points.len() {
            let n = self.points.len();
            let dir = (self.points[n - 1] - self.points[n - 2]).normalize();
            (end - pos).dot(&dir)
        } else {
            self.total() - self.s[self.closest]
        };
        if remaining <= 0.002 {
            return (0.0, 0.0, true);
        }
        let s_here = self.total() - remaining;
        let target = self.at(s_here + cfg.lookahead_m);
        let to_target = target - pos;
        let lateral = heading.perp(&to_target);
        let ld2 = to_target.norm_squared().max(1e-9);
        let curvature = 2.0 * lateral / ld2;
        // Speed: the cruise limit, the yaw-rate limit on this curvature, the stopping limit.
        let decel = PLAN_DECEL_FRACTION * cfg.max_accel_mps2;
        let v_curve = 0.9 * cfg.max_yaw_rate_rps / curvature.abs().max(1e-9);
        let v_stop = (2.0 * decel * remaining).sqrt();
        let v_cmd = cfg.max_speed_mps.min(v_curve).min(v_stop);
        let w_cmd = (v_now.max(0.0) * curvature).clamp(-cfg.max_yaw_rate_rps, cfg.max_yaw_rate_rps);
        (v_cmd, w_cmd, false)
    }
}
