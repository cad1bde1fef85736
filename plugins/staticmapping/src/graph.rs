//! The submap pose graph (StaticMapping's `IsamOptimizer`): a pose per submap, a prior of
//! σ = 1e-6 on the first, and between factors of σ = 0.1 rad and 0.15 m for consecutive
//! submaps (`frame_match_noise_model_`) and for loops (`loop_closure_noise_model_`); with
//! GNSS, position priors of σ = 0.15 m (`gps_noise_model_`, [`crate::gnss`]).

use nalgebra::{Isometry3, Vector3, Vector6};
use slam_common::factor_graph::backend::{
    self, Backend, BackendConfig, BackendError, Factor, FactorId, Profiled, Robust, Scope, Value,
    Var,
};

const PRIOR_SIGMA: f64 = 1e-6;
const MATCH_SIGMA_RAD: f64 = 0.1;
const MATCH_SIGMA_M: f64 = 0.15;

fn match_sigmas() -> Vector6<f64> {
    Vector6::new(
        MATCH_SIGMA_RAD,
        MATCH_SIGMA_RAD,
        MATCH_SIGMA_RAD,
        MATCH_SIGMA_M,
        MATCH_SIGMA_M,
        MATCH_SIGMA_M,
    )
}

#[derive(Debug)]
pub struct SubmapGraph {
    pub backend: Profiled,
    len: usize,
}

impl SubmapGraph {
    pub fn new(cfg: &BackendConfig) -> Result<Self, BackendError> {
        Ok(Self {
            backend: Profiled::new(backend::from_config(cfg)?),
            len: 0,
        })
    }

    pub fn len(&self) -> usize {
        self.len
    }

    pub fn is_empty(&self) -> bool {
        self.len == 0
    }

    /// Adds the first submap at `world_from_submap`, held by the prior.
    pub fn add_first(&mut self, world_from_submap: Isometry3<f64>) -> Result<(), BackendError> {
        self.backend
            .insert(Var::Pose(0), Value::Pose(world_from_submap))?;
        self.backend.add(Factor::PosePrior {
            key: 0,
            world_from_body: world_from_submap,
            sigmas: Vector6::repeat(PRIOR_SIGMA),
        })?;
        self.len = 1;
        self.backend.update(Scope::Incremental).map(|_| ())
    }

    /// Adds the next submap, `previous_from_current` from the last one, and updates.
    pub fn add_next(&mut self, previous_from_current: Isometry3<f64>) -> Result<(), BackendError> {
        let k = self.len as u64;
        let initial = self.pose(self.len - 1) * previous_from_current;
        self.backend.insert(Var::Pose(k), Value::Pose(initial))?;
        self.backend.add(Factor::Between {
            from: k - 1,
            to: k,
            from_from_to: previous_from_current,
            sigmas: match_sigmas(),
            robust: Robust::None,
        })?;
        self.len += 1;
        self.backend.update(Scope::Incremental).map(|_| ())
    }

    /// Adds loop edges `target_from_current` and optimises the whole graph.
    pub fn add_loops(
        &mut self,
        current: usize,
        edges: impl IntoIterator<Item = (usize, Isometry3<f64>)>,
    ) -> Result<(), BackendError> {
        for (target, target_from_current) in edges {
            self.backend.add(Factor::Between {
                from: target as u64,
                to: current as u64,
                from_from_to: target_from_current,
                sigmas: match_sigmas(),
                robust: Robust::None,
            })?;
        }
        self.backend.update(Scope::Full).map(|_| ())
    }

    /// Adds position priors (`submap`, the submap's origin in the graph's frame) of `sigma_m`
    /// on every axis and updates with `scope`; nothing without priors. The factors' ids, in
    /// order.
    pub fn add_positions(
        &mut self,
        priors: &[(usize, Vector3<f64>)],
        sigma_m: f64,
        scope: Scope,
    ) -> Result<Vec<FactorId>, BackendError> {
        if priors.is_empty() {
            return Ok(Vec::new());
        }
        let ids = priors
            .iter()
            .map(|&(k, position)| {
                self.backend.add(Factor::Position {
                    key: k as u64,
                    position,
                    sigmas: Vector3::repeat(sigma_m),
                })
            })
            .collect::<Result<Vec<_>, _>>()?;
        self.backend.update(scope)?;
        Ok(ids)
    }

    /// Removes factors (GNSS priors to be added again), without an update.
    pub fn remove_factors(&mut self, ids: &[FactorId]) {
        for &id in ids {
            let removed = self.backend.remove(id);
            debug_assert!(removed, "factor {id:?} was in the graph");
        }
    }

    /// The current estimate of submap `k`.
    pub fn pose(&self, k: usize) -> Isometry3<f64> {
        self.backend
            .pose(k as u64)
            .expect("every submap added has a pose")
    }
}
