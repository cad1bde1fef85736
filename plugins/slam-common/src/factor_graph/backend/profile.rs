//! [`Profiled`]: any backend with a log of its updates (graph size, scope, seconds), so a
//! plugin can show that its per-keyframe cost stays flat as the graph grows, whichever
//! backend its configuration names.

use std::fmt::Write as _;
use std::path::Path;
use std::time::Instant;

use nalgebra::Isometry3;

use super::{
    Backend, BackendError, Factor, FactorId, PoseCovariance, Scope, UpdateReport, Value, Var,
};

/// One update: poses in the graph, whether it was full, and how long it took.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct UpdateTiming {
    pub poses: usize,
    pub full: bool,
    pub seconds: f64,
}

/// A backend whose every [`update`](Backend::update) is timed.
#[derive(Debug)]
pub struct Profiled {
    inner: Box<dyn Backend>,
    poses: usize,
    log: Vec<UpdateTiming>,
}

impl Profiled {
    pub fn new(inner: Box<dyn Backend>) -> Self {
        Self {
            inner,
            poses: 0,
            log: Vec::new(),
        }
    }

    /// Every update so far, in order.
    pub fn timings(&self) -> &[UpdateTiming] {
        &self.log
    }

    /// The log as CSV: `poses,full,seconds`, one line per update.
    pub fn csv(&self) -> String {
        let mut out = String::from("poses,full,seconds\n");
        for t in &self.log {
            let _ = writeln!(out, "{},{},{:.6}", t.poses, u8::from(t.full), t.seconds);
        }
        out
    }

    pub fn write_csv(&self, path: &Path) -> std::io::Result<()> {
        std::fs::write(path, self.csv())
    }
}

impl Backend for Profiled {
    fn insert(&mut self, var: Var, initial: Value) -> Result<(), BackendError> {
        self.inner.insert(var, initial)?;
        if matches!(var, Var::Pose(_)) {
            self.poses += 1;
        }
        Ok(())
    }

    fn add(&mut self, factor: Factor) -> Result<FactorId, BackendError> {
        self.inner.add(factor)
    }

    fn remove(&mut self, id: FactorId) -> bool {
        self.inner.remove(id)
    }

    fn update(&mut self, scope: Scope) -> Result<UpdateReport, BackendError> {
        let start = Instant::now();
        let report = self.inner.update(scope)?;
        self.log.push(UpdateTiming {
            poses: self.poses,
            full: scope == Scope::Full,
            seconds: start.elapsed().as_secs_f64(),
        });
        Ok(report)
    }

    fn value(&self, var: Var) -> Option<Value> {
        self.inner.value(var)
    }

    fn set_value(&mut self, var: Var, value: Value) -> Result<(), BackendError> {
        self.inner.set_value(var, value)
    }

    fn factor_error(&self, id: FactorId) -> Option<f64> {
        self.inner.factor_error(id)
    }

    fn pose_keys(&self) -> Vec<u64> {
        self.inner.pose_keys()
    }

    fn marginal_covariance(&self, key: u64) -> Result<PoseCovariance, BackendError> {
        self.inner.marginal_covariance(key)
    }

    fn pose(&self, key: u64) -> Option<Isometry3<f64>> {
        self.inner.pose(key)
    }
}
