//! A factor as the backend keeps it between updates, and its factrs form.
//!
//! factrs graphs cannot drop a factor and factrs factors are not `Send`, so the backend
//! keeps its own description of each factor and builds a fresh factrs factor for every
//! update (Dellaert and Kaess, "Factor Graphs for Robot Perception", Foundations and
//! Trends in Robotics 6(1–2), 2017, §2: a factor is a residual, a noise model and the
//! keys it touches; here also an optional robust kernel).
//!
//! - Priors: `z ⊖ x = log(x⁻¹·z)`, an error in the body frame, rotation first.
//! - Between: factrs's `BetweenResidual` computes `(x_from·z) ⊖ x_to =
//!   log(x_to⁻¹·x_from·z)`, so `z` is `from_from_to` as our contract has it.
//! - Position: `t(x) − z` in the world frame (module `position`, GTSAM's `GPSFactor`).

use ::factrs::{
    containers::{Factor as FFactor, FactorBuilder, Key},
    noise::GaussianNoise,
    residuals::{BetweenResidual, PriorResidual},
    robust::{Cauchy, Huber},
};

use super::{BackendError, Factor, Robust, Var, convert, imu::Preintegrated, position};

#[derive(Debug, Clone)]
enum Kind {
    /// Any factor but an IMU one, kept as given.
    Plain(Factor),
    /// An IMU factor, preintegrated when it was added.
    Imu {
        from: u64,
        to: u64,
        preint: Box<Preintegrated>,
    },
}

#[derive(Debug, Clone)]
pub(crate) struct Entry {
    kind: Kind,
    vars: Vec<Var>,
}

impl Entry {
    /// Checks the factor and, for an IMU factor, preintegrates its samples; `bias` gives
    /// the current bias estimate of a keyframe (the linearisation point).
    pub(crate) fn new(
        factor: Factor,
        bias: impl Fn(u64) -> Option<super::ImuBias>,
    ) -> Result<Self, BackendError> {
        check(&factor)?;
        let vars = vars_of(&factor);
        let kind = match factor {
            Factor::Imu {
                from,
                to,
                samples,
                noise,
            } => {
                let b = bias(from).ok_or(BackendError::MissingVariable(Var::Bias(from)))?;
                let preint = Preintegrated::new(&samples, &noise, &b)?;
                Kind::Imu {
                    from,
                    to,
                    preint: Box::new(preint),
                }
            }
            other => Kind::Plain(other),
        };
        Ok(Self { kind, vars })
    }

    /// The variables this factor constrains.
    pub(crate) fn vars(&self) -> &[Var] {
        &self.vars
    }

    /// The factrs factor, keyed by `key`; `robust: false` drops the kernel (to measure
    /// the plain whitened error).
    pub(crate) fn build(&self, key: impl Fn(Var) -> Key, robust: bool) -> FFactor {
        match &self.kind {
            Kind::Imu { from, to, preint } => preint.factor(
                [
                    key(Var::Pose(*from)),
                    key(Var::Velocity(*from)),
                    key(Var::Bias(*from)),
                ],
                [
                    key(Var::Pose(*to)),
                    key(Var::Velocity(*to)),
                    key(Var::Bias(*to)),
                ],
            ),
            Kind::Plain(f) => plain(f, key, robust),
        }
    }
}

fn plain(f: &Factor, key: impl Fn(Var) -> Key, robust: bool) -> FFactor {
    match f {
        Factor::PosePrior {
            key: k,
            world_from_body,
            sigmas,
        } => FactorBuilder::new1_unchecked(
            PriorResidual::new(convert::se3_from_iso(world_from_body)),
            key(Var::Pose(*k)),
        )
        .noise(convert::pose_noise(sigmas))
        .build(),
        Factor::VelocityPrior {
            key: k,
            velocity_mps,
            sigma_mps,
        } => FactorBuilder::new1_unchecked(
            PriorResidual::new(convert::fvel(velocity_mps)),
            key(Var::Velocity(*k)),
        )
        .noise(GaussianNoise::<3>::from_scalar_sigma(*sigma_mps))
        .build(),
        Factor::BiasPrior {
            key: k,
            bias,
            sigma_accel,
            sigma_gyro,
        } => FactorBuilder::new1_unchecked(
            PriorResidual::new(convert::fbias(bias)),
            key(Var::Bias(*k)),
        )
        .noise(convert::bias_noise(*sigma_accel, *sigma_gyro))
        .build(),
        Factor::Position {
            key: k,
            position,
            sigmas,
        } => FactorBuilder::new1_unchecked(
            position::PositionResidual::new(*position),
            key(Var::Pose(*k)),
        )
        .noise(GaussianNoise::<3>::from_vec_sigma(sigmas.as_view()))
        .build(),
        Factor::Between {
            from,
            to,
            from_from_to,
            sigmas,
            robust: kernel,
        } => {
            let b = FactorBuilder::new2_unchecked(
                BetweenResidual::new(convert::se3_from_iso(from_from_to)),
                key(Var::Pose(*from)),
                key(Var::Pose(*to)),
            )
            .noise(convert::pose_noise(sigmas));
            match (robust, kernel) {
                (true, Robust::Huber(k)) => b.robust(Huber::new(*k)).build(),
                (true, Robust::Cauchy(k)) => b.robust(Cauchy::new(*k)).build(),
                _ => b.build(),
            }
        }
        // Entry::new keeps IMU factors as `Kind::Imu`; building one here would need its
        // samples, which are not kept.
        Factor::Imu { .. } => unreachable!("IMU factors are stored preintegrated"),
    }
}

pub(crate) fn vars_of(f: &Factor) -> Vec<Var> {
    match f {
        Factor::PosePrior { key, .. } | Factor::Position { key, .. } => vec![Var::Pose(*key)],
        Factor::VelocityPrior { key, .. } => vec![Var::Velocity(*key)],
        Factor::BiasPrior { key, .. } => vec![Var::Bias(*key)],
        Factor::Between { from, to, .. } => vec![Var::Pose(*from), Var::Pose(*to)],
        Factor::Imu { from, to, .. } => [*from, *to]
            .iter()
            .flat_map(|&k| [Var::Pose(k), Var::Velocity(k), Var::Bias(k)])
            .collect(),
    }
}

/// Rejects what factrs would turn into NaN or a panic: non-positive sigmas, non-finite
/// measurements, kernel widths that are not positive.
pub(crate) fn check(f: &Factor) -> Result<(), BackendError> {
    match f {
        Factor::PosePrior {
            world_from_body,
            sigmas,
            ..
        } => {
            convert::check_pose("pose prior", world_from_body)?;
            convert::check_positive("pose prior sigma", sigmas.as_slice())
        }
        Factor::VelocityPrior {
            velocity_mps,
            sigma_mps,
            ..
        } => {
            convert::check_finite("velocity prior", velocity_mps.as_slice())?;
            convert::check_positive("velocity prior sigma", &[*sigma_mps])
        }
        Factor::BiasPrior {
            bias,
            sigma_accel,
            sigma_gyro,
            ..
        } => {
            convert::check_value(&super::Value::Bias(*bias))?;
            convert::check_positive("bias prior sigma", &[*sigma_accel, *sigma_gyro])
        }
        Factor::Position {
            position, sigmas, ..
        } => {
            convert::check_finite("position prior", position.as_slice())?;
            convert::check_positive("position prior sigma", sigmas.as_slice())
        }
        Factor::Between {
            from,
            to,
            from_from_to,
            sigmas,
            robust,
        } => {
            distinct(from, to, "between factor from pose")?;
            convert::check_pose("between measurement", from_from_to)?;
            convert::check_positive("between sigma", sigmas.as_slice())?;
            match robust {
                Robust::None => Ok(()),
                Robust::Huber(k) | Robust::Cauchy(k) => {
                    convert::check_positive("robust kernel width", &[*k])
                }
            }
        }
        Factor::Imu {
            from,
            to,
            samples,
            noise,
        } => {
            distinct(from, to, "IMU factor from keyframe")?;
            super::imu::check(samples, noise)
        }
    }
}

/// A factor between two variables must join two different ones: `"{what} {from} to
/// itself"` otherwise.
fn distinct(from: &u64, to: &u64, what: &str) -> Result<(), BackendError> {
    if from == to {
        return Err(BackendError::Invalid(format!("{what} {from} to itself")));
    }
    Ok(())
}
