//! Body vibration: what the ground does to the robot's body as its wheels roll, felt by the
//! IMU and carried by every sensor on the body.
//!
//! Each of the body's six motions (x, y, z along the base's axes; roll, pitch, yaw) is a
//! stationary Gaussian process whose power spectrum is flat within each of a few frequency
//! bands, the RMS within each band given: the translations' as acceleration (what an
//! accelerometer measures), the rotations' as angular rate (a gyroscope's). It is
//! synthesised by the spectral representation method (Shinozuka & Deodatis 1991,
//! "Simulation of stochastic processes by spectral representation", Appl. Mech. Rev.
//! 44(4)): per band, `K` cosines with frequencies drawn uniformly within the band and phases
//! uniformly, each of amplitude `rms·√(2/K)`, so that the band's mean square is `rms²`.
//! Displacement and angle are the cosines' exact integrals, so that what the IMU reads and
//! where the lidar and camera are agree. The translations are those of the point where the
//! accelerations were measured (the IMU's mount: a measurement is of the IMU's own motion);
//! the base origin's is that less the rotation's lever, `u − θ × r` (small angles).
//!
//! The amplitude follows the speed the wheels roll at (the mean speed of the four contact
//! points), as `(v / v_ref)^p`: a robot at rest does not vibrate. The scaling is applied
//! quasi-statically (the amplitude's own rate of change is left out of the derivatives: at
//! the controller's 1 m/s² limit and 0.5 m/s reference that is under 2·(dm/dt)·|u'|, some
//! 0.1 m/s² for the 0.5–2 Hz band's 0.18 m/s² while the robot speeds up or slows down, and
//! nothing at a steady speed).

use std::f64::consts::TAU;

use rand::Rng;

use crate::config::VibrationConfig;
use crate::rng::SimRng;

/// One cosine of a channel: `amplitude·cos(omega·t + phase)` is the channel's second
/// derivative (translations) or first derivative (rotations).
#[derive(Debug, Clone, Copy)]
struct Component {
    amplitude: f64,
    omega: f64,
    phase: f64,
}

/// The six channels' cosines, drawn once per run.
#[derive(Debug, Clone)]
pub struct Vibration {
    /// x, y, z (acceleration, base axes), roll, pitch, yaw (angular rate).
    channels: [Vec<Component>; 6],
    reference_speed_mps: f64,
    speed_exponent: f64,
    /// Where the translations were measured, in the base frame (m).
    at_point: [f64; 3],
}

/// A channel's value and its first two time derivatives.
pub type Triple = [f64; 3];

impl Vibration {
    /// Draws the cosines from `rng`; `None` where every band's RMS is zero. `at_point`:
    /// where the accelerations were measured, in the base frame (the IMU's mount).
    pub fn new(cfg: &VibrationConfig, at_point: [f64; 3], rng: &mut SimRng) -> Option<Self> {
        let rms: Vec<&[f64]> = cfg
            .accel_rms_mps2
            .iter()
            .chain(&cfg.rate_rms_rps)
            .map(|bands| bands.as_slice())
            .collect();
        if rms.iter().all(|bands| bands.iter().all(|&r| r == 0.0)) {
            return None;
        }
        let k = cfg.components_per_band.max(1);
        let amplitude_per = (2.0 / k as f64).sqrt();
        let channels = std::array::from_fn(|c| {
            let mut out = Vec::new();
            for (band, &r) in cfg.bands_hz.windows(2).zip(rms[c]) {
                // Drawn even for a zero band, so that one band's RMS never moves another's
                // frequencies or phases.
                for _ in 0..k {
                    let f = band[0] + (band[1] - band[0]) * rng.random::<f64>();
                    let phase = TAU * rng.random::<f64>();
                    if r > 0.0 {
                        out.push(Component {
                            amplitude: r * amplitude_per,
                            omega: TAU * f,
                            phase,
                        });
                    }
                }
            }
            out
        });
        Some(Self {
            channels,
            reference_speed_mps: cfg.reference_speed_mps,
            speed_exponent: cfg.speed_exponent,
            at_point,
        })
    }

    /// The amplitude's scale at wheel speed `v` (m/s).
    pub fn scale(&self, v: f64) -> f64 {
        if v <= 0.0 {
            0.0
        } else {
            (v / self.reference_speed_mps).powf(self.speed_exponent)
        }
    }

    /// At `t_s`, unscaled: per channel the base origin's displacement (m, base axes) or the
    /// angle (rad) and its first two derivatives.
    pub fn at(&self, t_s: f64) -> [Triple; 6] {
        let mut ch: [Triple; 6] = std::array::from_fn(|c| {
            let translation = c < 3;
            let mut out = [0.0; 3];
            for k in &self.channels[c] {
                let (s, co) = (k.omega * t_s + k.phase).sin_cos();
                let a = k.amplitude;
                if translation {
                    // u'' = a cos, u' = a/ω sin, u = −a/ω² cos.
                    out[0] -= a / (k.omega * k.omega) * co;
                    out[1] += a / k.omega * s;
                    out[2] += a * co;
                } else {
                    // θ' = a cos, θ = a/ω sin, θ'' = −aω sin.
                    out[0] += a / k.omega * s;
                    out[1] += a * co;
                    out[2] -= a * k.omega * s;
                }
            }
            out
        });
        // The origin moves by u − θ × r where the measuring point moves by u; each
        // derivative likewise (r is fixed on the body).
        let r = self.at_point;
        let [roll, pitch, yaw] = [ch[3], ch[4], ch[5]];
        let lever = |o: usize| {
            [
                pitch[o] * r[2] - yaw[o] * r[1],
                yaw[o] * r[0] - roll[o] * r[2],
                roll[o] * r[1] - pitch[o] * r[0],
            ]
        };
        for (axis, channel) in ch[..3].iter_mut().enumerate() {
            for (order, value) in channel.iter_mut().enumerate() {
                *value -= lever(order)[axis];
            }
        }
        ch
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rng::stream;

    fn config() -> VibrationConfig {
        VibrationConfig {
            bands_hz: vec![0.5, 2.0, 5.0, 10.0, 25.0],
            accel_rms_mps2: [
                vec![0.2, 0.3, 0.3, 0.1],
                vec![0.1, 0.3, 0.2, 0.1],
                vec![0.1, 0.2, 0.5, 0.3],
            ],
            rate_rms_rps: [
                vec![0.03, 0.04, 0.01, 0.02],
                vec![0.03, 0.04, 0.02, 0.02],
                vec![0.01, 0.02, 0.02, 0.01],
            ],
            reference_speed_mps: 0.5,
            speed_exponent: 1.5,
            components_per_band: 8,
        }
    }

    /// The derivatives are the value's: a central difference of each agrees.
    #[test]
    fn derivatives_are_the_values_own() {
        let v = Vibration::new(&config(), [0.1, 0.0, 0.6], &mut stream(3, "vibration")).unwrap();
        let h = 1e-5;
        for t in [0.3, 17.0, 123.456] {
            let (a, b, c) = (v.at(t - h), v.at(t), v.at(t + h));
            for ch in 0..6 {
                let d = (c[ch][0] - a[ch][0]) / (2.0 * h);
                let dd = (c[ch][1] - a[ch][1]) / (2.0 * h);
                assert!(
                    (d - b[ch][1]).abs() < 1e-6 * (1.0 + d.abs()),
                    "ch {ch} t {t}"
                );
                assert!(
                    (dd - b[ch][2]).abs() < 1e-4 * (1.0 + dd.abs()),
                    "ch {ch} t {t}"
                );
            }
        }
    }

    #[test]
    fn rest_is_still_and_the_scale_follows_the_speed() {
        let v = Vibration::new(&config(), [0.1, 0.0, 0.6], &mut stream(3, "vibration")).unwrap();
        assert_eq!(v.scale(0.0), 0.0);
        assert!((v.scale(0.5) - 1.0).abs() < 1e-12);
        assert!((v.scale(0.25) - 0.5f64.powf(1.5)).abs() < 1e-12);
    }

    #[test]
    fn no_rms_is_no_vibration() {
        let mut cfg = config();
        cfg.accel_rms_mps2 = Default::default();
        cfg.rate_rms_rps = Default::default();
        assert!(Vibration::new(&cfg, [0.0; 3], &mut stream(3, "vibration")).is_none());
    }
}
