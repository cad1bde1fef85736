//! The ground-truth trajectory: a uniform cubic B-spline in time over x, y, z, yaw, pitch
//! and roll, so that position, attitude and their first two derivatives are continuous and
//! the IMU readings derived from it are physically consistent (the continuous-time
//! representation of Furgale et al., "Continuous-time batch estimation using temporal
//! basis functions", ICRA 2012).
//!
//! Control points are the controller's planar states every [`KNOT_DT_S`], lifted onto the
//! terrain: height from the mean of the four wheel contacts, pitch and roll from the height
//! differences between the front and rear and the left and right wheels.
//!
//! The body's vibration (`super::vibration`), where the world has one, rides on the spline:
//! [`Trajectory::pose`] and [`Trajectory::state`] are the vibrating body's (what the IMU,
//! the lidar, the cameras, the 2D scanners, GNSS and ground truth follow), and
//! [`Trajectory::nominal_pose`] and [`Trajectory::nominal_state`] the spline's alone (what
//! the wheel encoders count: the wheels roll along it while the body shakes on its tyres).

use nalgebra::{Isometry3, Matrix3, Translation3, UnitQuaternion, Vector3};

use super::controller::PlanarSample;
use super::vibration::Vibration;
use crate::config::RobotConfig;
use crate::world::Terrain;

/// Knot spacing of the spline.
pub const KNOT_DT_S: f64 = 0.05;
/// Standard gravity.
pub const GRAVITY: f64 = 9.80665;

const X: usize = 0;
const Y: usize = 1;
const Z: usize = 2;
const YAW: usize = 3;
const PITCH: usize = 4;
const ROLL: usize = 5;

/// The state of the base at one instant, all from the spline.
#[derive(Debug, Clone, Copy)]
pub struct State {
    pub world_from_base: Isometry3<f64>,
    /// Linear velocity and acceleration of the base origin, world frame.
    pub velocity: Vector3<f64>,
    pub acceleration: Vector3<f64>,
    /// Angular velocity and acceleration, base frame.
    pub omega_in_base: Vector3<f64>,
    pub alpha_in_base: Vector3<f64>,
}

/// A smooth trajectory defined from time 0 to `duration_ns`.
#[derive(Debug, Clone)]
pub struct Trajectory {
    ctrl: Vec<[f64; 6]>,
    duration_ns: i64,
    vibration: Option<Vibration>,
    /// The wheel contact points' offsets from the base (x, y), for the speed the wheels
    /// roll at, which scales the vibration.
    wheels: [[f64; 2]; 4],
}

impl Trajectory {
    /// Fits the spline to controller samples on the terrain.
    pub fn from_samples(samples: &[PlanarSample], terrain: &Terrain, robot: &RobotConfig) -> Self {
        let last = samples.last().expect("the controller returns samples");
        let knots = (last.t / KNOT_DT_S).floor() as usize + 1;
        let mut ctrl = Vec::with_capacity(knots + 4);
        let step = (KNOT_DT_S / super::controller::CONTROL_DT_S).round() as usize;
        for k in 0..knots {
            let s = &samples[(k * step).min(samples.len() - 1)];
            ctrl.push(lift(s, terrain, robot));
        }
        // Pad so that the spline is defined (and at rest) over the whole span.
        let (first, end) = (ctrl[0], *ctrl.last().expect("non-empty"));
        ctrl.insert(0, first);
        ctrl.extend([end, end]);
        let (wx, wy) = (robot.wheel_x_m, robot.wheel_y_m);
        Self {
            ctrl,
            duration_ns: ((knots - 1) as f64 * KNOT_DT_S * 1e9) as i64,
            vibration: None,
            wheels: [[wx, wy], [wx, -wy], [-wx, wy], [-wx, -wy]],
        }
    }

    /// The same trajectory with the body vibrating (`None`: still).
    pub fn with_vibration(mut self, vibration: Option<Vibration>) -> Self {
        self.vibration = vibration;
        self
    }

    pub fn duration_ns(&self) -> i64 {
        self.duration_ns
    }

    /// Pose at `t_ns` (clamped to the trajectory's span), the body vibrating.
    pub fn pose(&self, t_ns: i64) -> Isometry3<f64> {
        let [p, ..] = self.vibrating(t_ns);
        pose_of(&p)
    }

    /// The full state at `t_ns` (clamped to the trajectory's span), the body vibrating.
    pub fn state(&self, t_ns: i64) -> State {
        state_of(self.vibrating(t_ns))
    }

    /// Pose at `t_ns` along the spline alone, without the body's vibration.
    pub fn nominal_pose(&self, t_ns: i64) -> Isometry3<f64> {
        let [p, ..] = self.channels(t_ns);
        pose_of(&p)
    }

    /// The state at `t_ns` along the spline alone, without the body's vibration.
    pub fn nominal_state(&self, t_ns: i64) -> State {
        state_of(self.channels(t_ns))
    }

    /// The channels with the vibration added: its translations (base axes) turned by the
    /// heading into the world (with the heading's rate and acceleration, exactly), its
    /// rotations added to roll, pitch and yaw, all scaled by the wheels' speed.
    fn vibrating(&self, t_ns: i64) -> [[f64; 6]; 3] {
        let mut ch = self.channels(t_ns);
        let Some(vibration) = &self.vibration else {
            return ch;
        };
        let [p, d, dd] = &ch;
        let (vx, vy, wz) = (d[X], d[Y], d[YAW]);
        let (psi, dpsi, ddpsi) = (p[YAW], d[YAW], dd[YAW]);
        let (s, c) = psi.sin_cos();
        let speed = 0.25
            * self
                .wheels
                .iter()
                .map(|[ox, oy]| {
                    // The contact's offset in the world, and its velocity v + ω × r.
                    let (rx, ry) = (c * ox - s * oy, s * ox + c * oy);
                    (vx - wz * ry).hypot(vy + wz * rx)
                })
                .sum::<f64>();
        let m = vibration.scale(speed);
        if m == 0.0 {
            return ch;
        }
        let t_s = t_ns.clamp(0, self.duration_ns) as f64 * 1e-9;
        let v = vibration.at(t_s);
        // R u and J R u (J the quarter turn) for a planar vector u.
        let r = |u: [f64; 2]| [c * u[0] - s * u[1], s * u[0] + c * u[1]];
        let j = |w: [f64; 2]| [-w[1], w[0]];
        let (u, du, ddu) = ([v[X][0], v[Y][0]], [v[X][1], v[Y][1]], [v[X][2], v[Y][2]]);
        let (ru, rdu, rddu) = (r(u), r(du), r(ddu));
        let (jru, jrdu) = (j(ru), j(rdu));
        // w = R u; w' = R u' + ψ' J R u; w'' = R u'' + 2ψ' J R u' + ψ'' J R u − ψ'² R u.
        let w0 = ru;
        let w1 = [rdu[0] + dpsi * jru[0], rdu[1] + dpsi * jru[1]];
        let w2 = [
            rddu[0] + 2.0 * dpsi * jrdu[0] + ddpsi * jru[0] - dpsi * dpsi * ru[0],
            rddu[1] + 2.0 * dpsi * jrdu[1] + ddpsi * jru[1] - dpsi * dpsi * ru[1],
        ];
        for (order, w) in [w0, w1, w2].into_iter().enumerate() {
            ch[order][X] += m * w[0];
            ch[order][Y] += m * w[1];
            ch[order][Z] += m * v[Z][order];
            ch[order][ROLL] += m * v[3][order];
            ch[order][PITCH] += m * v[4][order];
            ch[order][YAW] += m * v[5][order];
        }
        ch
    }

    /// Value and first two time derivatives of all channels at `t_ns`.
    fn channels(&self, t_ns: i64) -> [[f64; 6]; 3] {
        let t = t_ns.clamp(0, self.duration_ns) as f64 * 1e-9 / KNOT_DT_S;
        // Segment i spans knots i..i+1 and uses control points i..i+4 (the first is padding).
        let i = (t.floor() as usize).min(self.ctrl.len() - 4);
        let u = t - i as f64;
        let (u2, u3) = (u * u, u * u * u);
        let w = [
            [
                (1.0 - u).powi(3) / 6.0,
                (3.0 * u3 - 6.0 * u2 + 4.0) / 6.0,
                (-3.0 * u3 + 3.0 * u2 + 3.0 * u + 1.0) / 6.0,
                u3 / 6.0,
            ],
            [
                -(1.0 - u).powi(2) / 2.0,
                (3.0 * u2 - 4.0 * u) / 2.0,
                (-3.0 * u2 + 2.0 * u + 1.0) / 2.0,
                u2 / 2.0,
            ],
            [1.0 - u, 3.0 * u - 2.0, 1.0 - 3.0 * u, u],
        ];
        let ctrl = &self.ctrl[i..i + 4];
        let mut out = [[0.0; 6]; 3];
        for ((order, weights), row) in w.iter().enumerate().zip(&mut out) {
            let scale = KNOT_DT_S.powi(-(order as i32));
            for (c, value) in row.iter_mut().enumerate() {
                *value = scale
                    * weights
                        .iter()
                        .zip(ctrl)
                        .map(|(wk, p)| wk * p[c])
                        .sum::<f64>();
            }
        }
        out
    }
}

/// The state of channels' value and first two derivatives.
fn state_of([p, d, dd]: [[f64; 6]; 3]) -> State {
    let (roll, pitch) = (p[ROLL], p[PITCH]);
    let (droll, dpitch, dyaw) = (d[ROLL], d[PITCH], d[YAW]);
    let (ddroll, ddpitch, ddyaw) = (dd[ROLL], dd[PITCH], dd[YAW]);
    let (sr, cr) = roll.sin_cos();
    let (sp, cp) = pitch.sin_cos();
    // Body rates of Z-Y-X Euler angles and their time derivative.
    let omega = Vector3::new(
        droll - dyaw * sp,
        dpitch * cr + dyaw * sr * cp,
        -dpitch * sr + dyaw * cr * cp,
    );
    let alpha = Vector3::new(
        ddroll - ddyaw * sp - dyaw * cp * dpitch,
        ddpitch * cr - dpitch * sr * droll
            + ddyaw * sr * cp
            + dyaw * (cr * droll * cp - sr * sp * dpitch),
        -ddpitch * sr - dpitch * cr * droll
            + ddyaw * cr * cp
            + dyaw * (-sr * droll * cp - cr * sp * dpitch),
    );
    State {
        world_from_base: pose_of(&p),
        velocity: Vector3::new(d[X], d[Y], d[Z]),
        acceleration: Vector3::new(dd[X], dd[Y], dd[Z]),
        omega_in_base: omega,
        alpha_in_base: alpha,
    }
}

fn pose_of(p: &[f64; 6]) -> Isometry3<f64> {
    Isometry3::from_parts(
        Translation3::new(p[X], p[Y], p[Z]),
        UnitQuaternion::from_euler_angles(p[ROLL], p[PITCH], p[YAW]),
    )
}

/// Puts a planar sample on the terrain.
fn lift(s: &PlanarSample, terrain: &Terrain, robot: &RobotConfig) -> [f64; 6] {
    let (sy, cy) = s.yaw.sin_cos();
    let h = |dx: f64, dy: f64| terrain.height(s.x + cy * dx - sy * dy, s.y + sy * dx + cy * dy);
    let (wx, wy) = (robot.wheel_x_m, robot.wheel_y_m);
    let (fl, fr, rl, rr) = (h(wx, wy), h(wx, -wy), h(-wx, wy), h(-wx, -wy));
    let z = 0.25 * (fl + fr + rl + rr);
    // Positive pitch is nose down, positive roll is left side up (Z-Y-X convention).
    let pitch = -(0.5 * (fl + fr) - 0.5 * (rl + rr)).atan2(2.0 * wx);
    let roll = (0.5 * (fl + rl) - 0.5 * (fr + rr)).atan2(2.0 * wy);
    [s.x, s.y, z, s.yaw, pitch, roll]
}

/// Rotation matrix of a pose, for the sensor models.
pub fn rotation(pose: &Isometry3<f64>) -> Matrix3<f64> {
    pose.rotation.to_rotation_matrix().into_inner()
}
