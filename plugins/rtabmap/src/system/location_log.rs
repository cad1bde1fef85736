//! `locations_csv`: every location's memory update and the time of the camera frame that
//! made it, for the study of RTAB-Map's memory management (`docs/systems/rtabmap.md`).

use std::time::Instant;

use crate::memory::Update;

/// When a camera frame's step began: the wall clock and this thread's CPU time.
#[derive(Debug, Clone, Copy)]
pub(super) struct StepStart {
    wall: Instant,
    cpu_ns: Option<u64>,
}

impl StepStart {
    pub(super) fn now() -> Self {
        Self {
            wall: Instant::now(),
            cpu_ns: thread_cpu_ns(),
        }
    }
}

/// A location's update and the time of the camera frame that made it.
#[derive(Debug, Clone, Copy)]
struct LocationTiming {
    id: u64,
    stamp_ns: i64,
    update: Update,
    step_ns: u128,
    /// CPU time of the thread over the same frame, if the system says (Linux), which unlike
    /// the wall time does not grow when other processes share the cores.
    step_cpu_ns: Option<u64>,
}

/// The rows of `locations_csv`.
#[derive(Debug, Default)]
pub(super) struct LocationLog {
    rows: Vec<LocationTiming>,
}

impl LocationLog {
    /// Location `id`, made at `stamp_ns` by a step that began at `start`.
    pub(super) fn push(&mut self, id: u64, stamp_ns: i64, update: Update, start: StepStart) {
        let step_ns = start.wall.elapsed().as_nanos();
        self.rows.push(LocationTiming {
            id,
            stamp_ns,
            update,
            step_ns,
            step_cpu_ns: start
                .cpu_ns
                .zip(thread_cpu_ns())
                .map(|(a, b)| b.saturating_sub(a)),
        });
    }

    /// The table.
    pub(super) fn csv(&self) -> String {
        let mut out = String::from(
            "location,stamp_ns,descriptors,new_words,vocabulary_words,comparisons,transferred,working_memory,step_ns,step_cpu_ns\n",
        );
        for t in &self.rows {
            let u = &t.update;
            out.push_str(&format!(
                "{},{},{},{},{},{},{},{},{},{}\n",
                t.id,
                t.stamp_ns,
                u.descriptors,
                u.new_words,
                u.vocabulary_words,
                u.comparisons,
                u.transferred,
                u.working_memory,
                t.step_ns,
                t.step_cpu_ns.map_or(String::new(), |ns| ns.to_string())
            ));
        }
        out
    }
}

/// CPU time this thread has run, ns (Linux: the first field of `/proc/thread-self/schedstat`).
fn thread_cpu_ns() -> Option<u64> {
    std::fs::read_to_string("/proc/thread-self/schedstat")
        .ok()?
        .split_whitespace()
        .next()?
        .parse()
        .ok()
}
