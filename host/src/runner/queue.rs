//! A system's subscriber queues on a paced run (`queue_size`): messages that arrive while the
//! system is busy wait in their topic's queue, a full queue drops its oldest, and what was
//! dropped is written to the run's `dropped.csv` — from which another run can be fed the
//! very same drops (`Job::drops`), whatever its own speed. See [`super::job::QueueSize`].

use std::collections::{BTreeMap, BTreeSet, VecDeque};
use std::path::Path;

use anyhow::Context as _;
use sim::sensors::Message;

use super::job::QueueSize;

/// The queues between the stream and the system.
#[derive(Debug, Default)]
pub struct Queues {
    size: Option<QueueSize>,
    /// Given drops, stamps by topic: these and only these are dropped.
    given: Option<BTreeMap<String, BTreeSet<i64>>>,
    /// Per topic, the messages waiting with their place in the stream.
    waiting: BTreeMap<&'static str, VecDeque<(u64, Message)>>,
    next_seq: u64,
    /// What was dropped, (topic, stamp), in the order it was.
    pub dropped: Vec<(&'static str, i64)>,
}

impl Queues {
    pub fn new(size: Option<QueueSize>, given: Option<BTreeSet<(String, i64)>>) -> Self {
        // By topic, so that a message is looked up without building its key.
        let given = given.map(|drops| {
            let mut by_topic: BTreeMap<String, BTreeSet<i64>> = BTreeMap::new();
            for (topic, stamp) in drops {
                by_topic.entry(topic).or_default().insert(stamp);
            }
            by_topic
        });
        Queues {
            size,
            given,
            ..Queues::default()
        }
    }

    /// A message has arrived: into its topic's queue, dropping that queue's oldest when it
    /// is full (or dropped itself when the given drops name it).
    pub fn push(&mut self, message: Message) {
        let topic = message.sensor();
        if let Some(given) = &self.given {
            if given
                .get(topic)
                .is_some_and(|stamps| stamps.contains(&message.stamp_ns()))
            {
                self.dropped.push((topic, message.stamp_ns()));
                return;
            }
        } else if let Some(n) = self.size.as_ref().and_then(|s| s.of(topic)) {
            let queue = self.waiting.entry(topic).or_default();
            while queue.len() >= n.max(1) {
                if let Some((_, old)) = queue.pop_front() {
                    self.dropped.push((topic, old.stamp_ns()));
                }
            }
        }
        self.waiting
            .entry(topic)
            .or_default()
            .push_back((self.next_seq, message));
        self.next_seq += 1;
    }

    /// The message that arrived first of those waiting, as a single-threaded spinner takes
    /// them.
    pub fn pop(&mut self) -> Option<Message> {
        let topic = *self
            .waiting
            .iter()
            .filter_map(|(topic, q)| q.front().map(|(seq, _)| (*seq, topic)))
            .min()?
            .1;
        self.waiting.get_mut(topic)?.pop_front().map(|(_, m)| m)
    }

    /// Drops per topic.
    pub fn counts(&self) -> BTreeMap<String, u64> {
        let mut counts = BTreeMap::new();
        for (topic, _) in &self.dropped {
            *counts.entry((*topic).to_owned()).or_insert(0) += 1;
        }
        counts
    }

    /// `dropped.csv`: `topic,stamp_ns`, in stamp order.
    pub fn csv(&self) -> String {
        let mut rows: Vec<(i64, &str)> = self.dropped.iter().map(|(t, s)| (*s, *t)).collect();
        rows.sort_unstable();
        let mut text = String::from("topic,stamp_ns\n");
        for (stamp, topic) in rows {
            text += &format!("{topic},{stamp}\n");
        }
        text
    }
}

/// Reads a `dropped.csv` ([`Queues::csv`]).
pub fn read_drops(path: &Path) -> anyhow::Result<BTreeSet<(String, i64)>> {
    let text = std::fs::read_to_string(path).with_context(|| path.display().to_string())?;
    let mut lines = text.lines();
    anyhow::ensure!(
        lines.next() == Some("topic,stamp_ns"),
        "{}: not a dropped.csv (its first line must be topic,stamp_ns)",
        path.display()
    );
    lines
        .enumerate()
        .filter(|(_, l)| !l.trim().is_empty())
        .map(|(i, line)| {
            let bad = || {
                anyhow::anyhow!(
                    "{}: line {}: expected topic,stamp_ns",
                    path.display(),
                    i + 2
                )
            };
            let (topic, stamp) = line.split_once(',').ok_or_else(bad)?;
            Ok((topic.to_owned(), stamp.trim().parse().map_err(|_| bad())?))
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::Vector3;
    use sim::sensors::{ImuSample, Message};

    fn imu(stamp_ns: i64) -> Message {
        Message::Imu(ImuSample {
            stamp_ns,
            accel_mps2: Vector3::zeros(),
            gyro_rps: Vector3::zeros(),
            orientation: None,
        })
    }

    /// roscpp's rule: a full queue drops its oldest; the rest come out in arrival order.
    #[test]
    fn a_full_queue_drops_its_oldest() {
        let mut q = Queues::new(Some(QueueSize::All(2)), None);
        for s in 1..=5 {
            q.push(imu(s));
        }
        assert_eq!(q.dropped, [("imu", 1), ("imu", 2), ("imu", 3)]);
        assert_eq!(q.pop().map(|m| m.stamp_ns()), Some(4));
        assert_eq!(q.pop().map(|m| m.stamp_ns()), Some(5));
        assert!(q.pop().is_none());
        assert_eq!(q.counts()["imu"], 3);
        assert_eq!(q.csv(), "topic,stamp_ns\nimu,1\nimu,2\nimu,3\n");
        // A topic not named is unbounded.
        let mut q = Queues::new(
            Some(QueueSize::Topics([("lidar".to_owned(), 1)].into())),
            None,
        );
        for s in 1..=5 {
            q.push(imu(s));
        }
        assert!(q.dropped.is_empty());
    }

    /// Given drops: exactly those, whatever the queues would do; read back from the csv.
    #[test]
    fn given_drops_are_dropped_and_only_they() {
        let dir = tempfile::tempdir().expect("tempdir");
        let path = dir.path().join("dropped.csv");
        std::fs::write(&path, "topic,stamp_ns\nimu,2\nimu,4\n").expect("write");
        let given = read_drops(&path).expect("read");
        let mut q = Queues::new(Some(QueueSize::All(1)), Some(given));
        let mut out = Vec::new();
        for s in 1..=5 {
            q.push(imu(s));
            out.extend(q.pop().map(|m| m.stamp_ns()));
        }
        assert_eq!(out, [1, 3, 5]);
        assert_eq!(q.dropped, [("imu", 2), ("imu", 4)]);
        std::fs::write(&path, "topic,stamp_ns\nimu,x\n").expect("write");
        let err = read_drops(&path).expect_err("bad").to_string();
        assert!(err.contains("line 2"), "{err}");
    }
}
