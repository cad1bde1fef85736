//! One simulation feeding several workers: the supervisor simulates a scenario once, with
//! every sensor its group of runs needs, and streams each worker (still its own process,
//! with its own limits) the messages of its plugin's sensors over the worker's stdin.
//!
//! The same messages as the worker's own simulation would give, bit for bit: every sensor
//! draws its noise from its own seeded stream (`sim::rng::stream(seed, sensor)`), so which
//! other sensors run beside it changes nothing, and every message travels as the ROS 2
//! messages a recording holds (the host's one message codec, [`crate::dataset::to_ros`] and
//! [`crate::dataset::Assembler`]), which carry every value's exact bits.
//! `host/tests/e2e/bench.rs` checks that shared and unshared runs give the same estimates.
//!
//! Framing (little-endian): frames of `tag: u8`, `ready_ns: i64` (when the message became
//! available, as a recording's log time), `length: u64`, `payload` (CDR); the tag is the
//! topic's index in [`Topic::ALL`], and tag [`END`] (empty payload) closes a complete stream,
//! so a worker whose stream stops without it knows the simulation did not finish.
//!
//! A worker that dies stops being fed (its pipe breaks); one that takes no message for
//! [`Feed::stall`] is cut off (it hangs: its own timeout will end it) so that the others go
//! on. A slow worker sets the pace of its group: the simulation runs at most [`AHEAD`]
//! messages ahead of each.

use std::io::{BufRead, BufReader, BufWriter, Read, Write};
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::mpsc::{Receiver, SyncSender, TrySendError, sync_channel};
use std::sync::{Arc, Mutex, OnceLock};
use std::time::{Duration, Instant};

use sim::sensors::Message;
use sim::{SensorSet, Simulation};

use super::timing::SimulationCost;
use crate::dataset::{Assembler, Topic, WireDetails, to_ros};

/// Messages the simulation may run ahead of a worker (as in a worker's own simulation).
pub const AHEAD: usize = 256;

/// Tag of the frame that closes a complete stream; any other tag is a topic's index in
/// [`Topic::ALL`].
const END: u8 = u8::MAX;

/// Largest payload a reader accepts (a 4K RGB-D frame's depth image is about 33 MB).
const MAX_PAYLOAD: u64 = 1 << 30;

/// Whether `sensors` includes the sensor of `message`.
pub fn wants(sensors: &SensorSet, message: &Message) -> bool {
    match message {
        Message::GroundTruth(_) => sensors.ground_truth,
        Message::Imu(_) => sensors.imu,
        Message::WheelOdometry(_) => sensors.wheel_odometry,
        Message::Lidar(_) => sensors.lidar,
        Message::Scan2d(_) => sensors.scan2d,
        Message::Rgbd(_) => sensors.rgbd,
        Message::Gnss(_) => sensors.gnss,
    }
}

/// Every sensor of any of the sets.
pub fn union(sets: &[SensorSet]) -> SensorSet {
    sets.iter().fold(SensorSet::default(), |a, b| SensorSet {
        ground_truth: a.ground_truth | b.ground_truth,
        imu: a.imu | b.imu,
        wheel_odometry: a.wheel_odometry | b.wheel_odometry,
        lidar: a.lidar | b.lidar,
        scan2d: a.scan2d | b.scan2d,
        rgbd: a.rgbd | b.rgbd,
        gnss: a.gnss | b.gnss,
    })
}

// ---------------------------------------------------------------------------------------
// Encoding

/// One message as the frames of its ROS 2 messages ([`crate::dataset::to_ros`]), each kept
/// as its own buffer: a lane writes a frame's 17-byte head and then its payload straight
/// to the worker's pipe, so a camera frame's images are not copied into one buffer first.
#[derive(Debug, Clone, PartialEq)]
pub struct Frames(Vec<(u8, i64, Vec<u8>)>);

impl Frames {
    /// The frames of `message`.
    pub fn encode(message: &Message, timing: &WireDetails) -> Self {
        Self(
            to_ros(message, timing)
                .into_iter()
                .map(|(topic, ready_ns, data)| {
                    let tag = Topic::ALL
                        .iter()
                        .position(|&t| t == topic)
                        .expect("every topic is in Topic::ALL") as u8;
                    (tag, ready_ns, data)
                })
                .collect(),
        )
    }

    /// The frame that closes a complete stream.
    pub fn end() -> Self {
        Self(vec![(END, 0, Vec::new())])
    }

    /// Writes each frame: `tag`, `ready_ns`, `length`, then the payload.
    pub fn write_to(&self, out: &mut impl Write) -> std::io::Result<()> {
        for (tag, ready_ns, payload) in &self.0 {
            let mut head = [0u8; 17];
            head[0] = *tag;
            head[1..9].copy_from_slice(&ready_ns.to_le_bytes());
            head[9..].copy_from_slice(&(payload.len() as u64).to_le_bytes());
            out.write_all(&head)?;
            out.write_all(payload)?;
        }
        Ok(())
    }

    /// The frames as one buffer, as a worker reads them.
    #[cfg(test)]
    fn to_bytes(&self) -> Vec<u8> {
        let mut out = Vec::new();
        self.write_to(&mut out).expect("writing to memory");
        out
    }
}

// ---------------------------------------------------------------------------------------
// Decoding

/// Why a stream could not be read.
#[derive(Debug, thiserror::Error)]
pub enum FeedError {
    #[error("the shared simulation stopped before the end of the route (no end mark)")]
    Truncated,
    #[error("malformed message from the shared simulation: {0}")]
    Malformed(String),
    #[error("reading the shared simulation: {0}")]
    Io(#[from] std::io::Error),
}

/// Reads a stream of frames (a worker's stdin) as messages. Ends at the end mark; an error
/// (a stream cut short, a malformed frame) ends the iteration and is kept for [`Self::error`].
#[derive(Debug)]
pub struct FeedReader<R: Read> {
    input: BufReader<R>,
    assembler: Assembler,
    done: bool,
    error: Arc<Mutex<Option<FeedError>>>,
}

impl<R: Read> FeedReader<R> {
    pub fn new(input: R) -> Self {
        Self {
            input: BufReader::with_capacity(1 << 20, input),
            assembler: Assembler::default(),
            done: false,
            error: Arc::default(),
        }
    }

    /// Where the reading error lands, readable after the reader has moved to another thread.
    pub fn error_slot(&self) -> Arc<Mutex<Option<FeedError>>> {
        Arc::clone(&self.error)
    }

    /// A payload of `len` bytes: what the buffer holds of it, then the rest read straight
    /// from the input, so that a large payload (an image) is not copied through the buffer.
    fn payload(&mut self, len: usize) -> std::io::Result<Vec<u8>> {
        let mut payload = Vec::with_capacity(len);
        let buffered = &self.input.buffer()[..len.min(self.input.buffer().len())];
        payload.extend_from_slice(buffered);
        let n = buffered.len();
        self.input.consume(n);
        let rest = (len - n) as u64;
        self.input.get_mut().take(rest).read_to_end(&mut payload)?;
        if payload.len() < len {
            return Err(std::io::ErrorKind::UnexpectedEof.into());
        }
        Ok(payload)
    }

    /// The next message; `None` at the end mark.
    fn next_frame(&mut self) -> Result<Option<Message>, FeedError> {
        let truncated = |e: std::io::Error| match e.kind() {
            std::io::ErrorKind::UnexpectedEof => FeedError::Truncated,
            _ => e.into(),
        };
        loop {
            let mut head = [0u8; 17];
            self.input.read_exact(&mut head).map_err(truncated)?;
            if head[0] == END {
                return Ok(None);
            }
            let topic = *Topic::ALL
                .get(usize::from(head[0]))
                .ok_or_else(|| FeedError::Malformed(format!("unknown topic tag {}", head[0])))?;
            let ready_ns = i64::from_le_bytes(head[1..9].try_into().expect("8 bytes"));
            let len = u64::from_le_bytes(head[9..].try_into().expect("8 bytes"));
            if len > MAX_PAYLOAD {
                return Err(FeedError::Malformed(format!(
                    "{} frame larger than 1 GiB",
                    topic.name()
                )));
            }
            let payload = self.payload(len as usize).map_err(truncated)?;
            let message = self
                .assembler
                .push(topic, ready_ns, &payload)
                .map_err(|e| FeedError::Malformed(format!("{}: {e}", topic.name())))?;
            if message.is_some() {
                return Ok(message);
            }
        }
    }
}

impl<R: Read> Iterator for FeedReader<R> {
    type Item = Message;

    fn next(&mut self) -> Option<Message> {
        if self.done {
            return None;
        }
        match self.next_frame() {
            Ok(Some(m)) => Some(m),
            Ok(None) => {
                self.done = true;
                None
            }
            Err(e) => {
                self.done = true;
                *self.error.lock().expect("no panic holds this lock") = Some(e);
                None
            }
        }
    }
}

// ---------------------------------------------------------------------------------------
// The supervisor's side

/// One worker fed by a [`Feed`].
#[derive(Debug)]
pub struct Subscriber<W: Write + Send> {
    /// Its plugin's sensors (ground truth always).
    pub sensors: SensorSet,
    /// Its stdin.
    pub input: W,
}

/// Streams one simulation to several workers.
#[derive(Debug, Clone)]
pub struct Feed {
    /// Simulated time to stop at (the route limit), ns; `None`: the whole route.
    pub end_ns: Option<i64>,
    /// What the ROS messages carry that the simulator's do not (the 2D scanners' timing,
    /// the camera's lens).
    pub wire_details: WireDetails,
    /// A worker that takes no message for this long is cut off.
    pub stall: Duration,
    /// What the simulation cost per sensor, set once it has run to its end (before the end
    /// mark goes out, so before any worker can finish).
    pub cost: Arc<OnceLock<SimulationCost>>,
}

/// How a worker's feeding ended.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Delivery {
    /// Every message and the end mark.
    Complete,
    /// It stopped reading (it exited or crashed) after `sent` messages.
    Closed { sent: usize },
    /// It took no message for the stall time after `sent` messages, and was cut off.
    Stalled { sent: usize },
}

/// One worker's queue and the thread that writes it out.
struct Lane {
    sensors: SensorSet,
    queue: Option<SyncSender<Arc<Frames>>>,
    sent: usize,
    outcome: Option<Delivery>,
    /// How long its writer has been blocked on the worker's pipe.
    clock: Arc<WriteClock>,
}

/// When a lane's writer started the write it is in, shared with the feed.
#[derive(Debug)]
struct WriteClock {
    epoch: Instant,
    /// Nanoseconds after `epoch` plus one; 0 while it writes nothing (or waits for frames).
    since: AtomicU64,
}

impl WriteClock {
    fn new() -> Self {
        Self {
            epoch: Instant::now(),
            since: AtomicU64::new(0),
        }
    }

    /// Runs `write`, noting when it started.
    fn timed<T>(&self, write: impl FnOnce() -> T) -> T {
        let ns = u64::try_from(self.epoch.elapsed().as_nanos()).unwrap_or(u64::MAX - 1);
        self.since.store(ns + 1, Ordering::Relaxed);
        let result = write();
        self.since.store(0, Ordering::Relaxed);
        result
    }

    /// How long the write in progress has been blocked (zero when there is none).
    fn stuck(&self) -> Duration {
        match self.since.load(Ordering::Relaxed) {
            0 => Duration::ZERO,
            since => self
                .epoch
                .elapsed()
                .saturating_sub(Duration::from_nanos(since - 1)),
        }
    }
}

/// Writes frames from `queue` to `out`, flushing whenever the queue runs dry, each write
/// timed on `clock`; returns whether everything was written.
fn write_lane(mut out: impl Write, queue: &Receiver<Arc<Frames>>, clock: &WriteClock) -> bool {
    let mut out = BufWriter::with_capacity(1 << 16, &mut out);
    loop {
        let frame = match queue.try_recv() {
            Ok(f) => f,
            Err(std::sync::mpsc::TryRecvError::Empty) => {
                if clock.timed(|| out.flush()).is_err() {
                    return false;
                }
                match queue.recv() {
                    Ok(f) => f,
                    Err(_) => break,
                }
            }
            Err(std::sync::mpsc::TryRecvError::Disconnected) => break,
        };
        if clock.timed(|| frame.write_to(&mut out)).is_err() {
            return false;
        }
    }
    out.flush().is_ok()
}

impl Feed {
    /// Simulates `sim` with every subscriber's sensors and streams each its messages;
    /// returns how each subscriber's feeding ended, in order. `Err`: the simulation itself
    /// failed (its subscribers got no end mark).
    pub fn run<W: Write + Send>(
        &self,
        sim: &Simulation,
        subscribers: Vec<Subscriber<W>>,
    ) -> Result<Vec<Delivery>, String> {
        let sensors = union(&subscribers.iter().map(|s| s.sensors).collect::<Vec<_>>());
        std::thread::scope(|scope| {
            let mut lanes = Vec::new();
            for sub in subscribers {
                let (tx, rx) = sync_channel::<Arc<Frames>>(AHEAD);
                let input = sub.input;
                let clock = Arc::new(WriteClock::new());
                let writer = {
                    let clock = Arc::clone(&clock);
                    scope.spawn(move || write_lane(input, &rx, &clock))
                };
                lanes.push((
                    Lane {
                        sensors: sub.sensors,
                        queue: Some(tx),
                        sent: 0,
                        outcome: None,
                        clock,
                    },
                    writer,
                ));
            }
            let end = self.end_ns;
            // The simulator produces ahead on its own thread, as in a worker.
            let (sim_tx, sim_rx) = sync_channel::<Message>(AHEAD);
            let producer = scope.spawn(move || {
                let mut cost = SimulationCost::default();
                let mut stream = sim.stream(sensors);
                while let Some(m) = cost.next_from(&mut stream) {
                    if end.is_some_and(|e| m.stamp_ns() > e) || sim_tx.send(m).is_err() {
                        break;
                    }
                }
                cost
            });
            for message in sim_rx {
                let frame = Arc::new(Frames::encode(&message, &self.wire_details));
                self.offer(
                    lanes
                        .iter_mut()
                        .map(|(lane, _)| lane)
                        .filter(|lane| wants(&lane.sensors, &message))
                        .collect(),
                    &frame,
                );
                if lanes.iter().all(|(l, _)| l.queue.is_none()) {
                    break;
                }
            }
            let simulated = match producer.join() {
                Ok(cost) => {
                    let _ = self.cost.set(cost);
                    true
                }
                Err(_) => false,
            };
            if simulated {
                self.offer(
                    lanes.iter_mut().map(|(lane, _)| lane).collect(),
                    &Arc::new(Frames::end()),
                );
            }
            let mut outcomes = Vec::new();
            for (mut lane, writer) in lanes {
                let sent = lane.sent;
                lane.queue = None;
                let written = writer.join().unwrap_or(false);
                outcomes.push(lane.outcome.unwrap_or(if written {
                    Delivery::Complete
                } else {
                    Delivery::Closed { sent }
                }));
            }
            if simulated {
                Ok(outcomes)
            } else {
                Err("the simulator panicked".to_owned())
            }
        })
    }

    /// Queues a frame for each of `lanes`, waiting while their queues are full; a lane whose
    /// worker is gone is closed, and one whose writer has been blocked writing to its worker
    /// for the stall time is cut off. Each lane's stall is timed from when its own pipe
    /// stopped draining, not from when the feed came to wait on it, so the waits for
    /// workers that hang at about the same time overlap.
    fn offer(&self, mut lanes: Vec<&mut Lane>, frame: &Arc<Frames>) {
        let mut nap = Duration::from_micros(50);
        loop {
            lanes.retain_mut(|lane| {
                let Some(queue) = &lane.queue else {
                    return false;
                };
                match queue.try_send(Arc::clone(frame)) {
                    Ok(()) => {
                        lane.sent += 1;
                        false
                    }
                    Err(TrySendError::Disconnected(_)) => {
                        lane.outcome = Some(Delivery::Closed { sent: lane.sent });
                        lane.queue = None;
                        false
                    }
                    Err(TrySendError::Full(_)) if lane.clock.stuck() > self.stall => {
                        lane.outcome = Some(Delivery::Stalled { sent: lane.sent });
                        lane.queue = None;
                        false
                    }
                    Err(TrySendError::Full(_)) => true,
                }
            });
            if lanes.is_empty() {
                return;
            }
            // Back off from 50 µs to 2 ms: prompt for a fast worker, idle for a slow one.
            std::thread::sleep(nap);
            nap = (nap * 2).min(Duration::from_millis(2));
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every kind of message of a short simulation with all sensors (a GNSS receiver too)
    /// survives the wire bit for bit.
    #[test]
    fn every_message_round_trips_exactly() {
        let mut config = sim::SimConfig::default();
        config.sensors.gnss.profile = sim::config::GnssProfile::Rtk;
        let timing = WireDetails::new(&config);
        let sim = Simulation::new(&config, "s1", 7).expect("s1");
        let mut kinds = std::collections::BTreeSet::new();
        for message in sim
            .stream(SensorSet::ALL)
            .take_while(|m| m.stamp_ns() < 150_000_000)
        {
            kinds.insert(message.sensor());
            let bytes = Frames::encode(&message, &timing).to_bytes();
            let mut reader = FeedReader::new(&bytes[..]);
            let back = reader.next_frame().expect("decodes").expect("a message");
            assert_eq!(back, message, "{} changed on the wire", message.sensor());
            // Bitwise, not just ==: -0.0 and NaN payloads too.
            assert_eq!(Frames::encode(&back, &timing).to_bytes(), bytes);
        }
        assert_eq!(kinds.len(), 8, "every sensor seen: {kinds:?}");
    }

    #[test]
    fn a_stream_without_its_end_mark_is_an_error() {
        let timing = WireDetails::new(&sim::SimConfig::default());
        let gt = Message::GroundTruth(sim::sensors::GroundTruth {
            stamp_ns: 5,
            world_from_base: nalgebra::Isometry3::identity(),
            velocity_in_world: nalgebra::Vector3::x(),
            omega_in_base: nalgebra::Vector3::z(),
        });
        let mut bytes = Frames::encode(&gt, &timing).to_bytes();
        let mut reader = FeedReader::new(&bytes[..]);
        let slot = reader.error_slot();
        assert_eq!(reader.next(), Some(gt.clone()));
        assert_eq!(reader.next(), None);
        assert!(matches!(*slot.lock().unwrap(), Some(FeedError::Truncated)));

        bytes.extend(Frames::end().to_bytes());
        let mut reader = FeedReader::new(&bytes[..]);
        let slot = reader.error_slot();
        assert_eq!(reader.by_ref().count(), 1);
        assert!(slot.lock().unwrap().is_none(), "a complete stream");

        // A frame cut in the middle, and a length beyond the payload.
        let cut = &bytes[..bytes.len() - 20];
        let mut reader = FeedReader::new(cut);
        let slot = reader.error_slot();
        assert_eq!(reader.by_ref().count(), 0);
        assert!(matches!(*slot.lock().unwrap(), Some(FeedError::Truncated)));

        // A payload that is not its topic's message, and an unknown tag.
        for (tag, payload) in [(5u8, vec![0u8; 40]), (200, vec![])] {
            let bad = Frames(vec![(tag, 0, payload)]).to_bytes();
            let mut reader = FeedReader::new(&bad[..]);
            let slot = reader.error_slot();
            assert_eq!(reader.by_ref().count(), 0);
            let error = slot.lock().unwrap().take().expect("an error").to_string();
            assert!(
                error.starts_with("malformed message from the shared simulation: "),
                "{error}"
            );
        }
    }

    /// Each subscriber gets its own sensors only, in order, then the end mark; one that
    /// stops reading is closed without holding up the others.
    #[test]
    fn feeds_each_its_sensors_and_survives_a_dead_reader() {
        let config = sim::SimConfig::default();
        let sim = Simulation::new(&config, "s0", 3).expect("s0");
        let imu_only = SensorSet {
            ground_truth: true,
            imu: true,
            ..SensorSet::default()
        };
        let odom_only = SensorSet {
            ground_truth: true,
            wheel_odometry: true,
            ..SensorSet::default()
        };
        let pipe = || std::os::unix::net::UnixStream::pair().expect("socket pair");
        let (a_write, a_read) = pipe();
        let (b_write, b_read) = pipe();
        let (c_write, c_read) = pipe();
        drop(c_read); // a worker that died at once
        let feed = Feed {
            end_ns: Some(2_000_000_000),
            stall: Duration::from_secs(30),
            wire_details: WireDetails::new(&config),
            cost: Arc::default(),
        };
        let readers = std::thread::spawn(move || {
            let a: Vec<Message> = FeedReader::new(a_read).collect();
            let b: Vec<Message> = FeedReader::new(b_read).collect();
            (a, b)
        });
        // b is read only after a is complete: the feed must keep a's lane going meanwhile
        // (b's queue holds up to AHEAD messages; 2 s of gt + odom is fewer).
        let outcomes = feed
            .run(
                &sim,
                vec![
                    Subscriber {
                        sensors: imu_only,
                        input: a_write,
                    },
                    Subscriber {
                        sensors: odom_only,
                        input: b_write,
                    },
                    Subscriber {
                        sensors: imu_only,
                        input: c_write,
                    },
                ],
            )
            .expect("simulates");
        let (a, b) = readers.join().expect("readers");
        assert_eq!(outcomes[0], Delivery::Complete);
        assert_eq!(outcomes[1], Delivery::Complete);
        assert!(
            matches!(outcomes[2], Delivery::Closed { .. }),
            "{:?}",
            outcomes[2]
        );
        let own = |set: SensorSet| -> Vec<Message> {
            sim.stream(set)
                .take_while(|m| m.stamp_ns() <= 2_000_000_000)
                .collect()
        };
        assert_eq!(
            a,
            own(imu_only),
            "a got exactly its own simulation's stream"
        );
        assert_eq!(
            b,
            own(odom_only),
            "b got exactly its own simulation's stream"
        );
        assert!(a.iter().any(|m| matches!(m, Message::Imu(_))));
        // The simulation's cost is noted for every sensor the group needed, and none else.
        let cost = feed.cost.get().expect("set once the simulation ended");
        let per_s = cost.per_simulated_s(2.0);
        assert_eq!(
            per_s.keys().map(String::as_str).collect::<Vec<_>>(),
            ["gt", "imu", "odom"],
            "{per_s:?}"
        );
        assert!(per_s.values().all(|&c| c > 0.0), "{per_s:?}");
    }
    /// A group goes on without its hung workers: two workers that never read are cut off
    /// (each costs the group at most one stall time), long before their own end, and a
    /// healthy worker beside them gets its whole stream.
    #[test]
    fn a_group_goes_on_without_its_hung_workers() {
        let config = sim::SimConfig::default();
        let sim = Simulation::new(&config, "s0", 3).expect("s0");
        let imu = SensorSet {
            ground_truth: true,
            imu: true,
            ..SensorSet::default()
        };
        let stall = Duration::from_secs(2);
        let feed = Feed {
            // 20 s of IMU and ground truth: more than a socket's buffer and a lane's queue.
            end_ns: Some(20_000_000_000),
            stall,
            wire_details: WireDetails::new(&config),
            cost: Arc::default(),
        };
        let pipe = || std::os::unix::net::UnixStream::pair().expect("socket pair");
        let (healthy_write, healthy_read) = pipe();
        let started = Instant::now();
        let healthy = std::thread::spawn(move || {
            let n = FeedReader::new(healthy_read).count();
            (n, started.elapsed())
        });
        let mut subscribers = vec![Subscriber {
            sensors: imu,
            input: healthy_write,
        }];
        let mut hung = Vec::new();
        for _ in 0..2 {
            let (write, read) = pipe();
            subscribers.push(Subscriber {
                sensors: imu,
                input: write,
            });
            // Never reads; dies (as its timeout would kill it) five stall times later.
            hung.push(std::thread::spawn(move || {
                std::thread::sleep(stall * 5);
                drop(read);
            }));
        }
        let outcomes = feed.run(&sim, subscribers).expect("simulates");
        let (n, took) = healthy.join().expect("healthy reader");
        hung.into_iter()
            .for_each(|h| h.join().expect("hung reader"));
        assert_eq!(outcomes[0], Delivery::Complete);
        for o in &outcomes[1..] {
            assert!(matches!(o, Delivery::Stalled { .. }), "{o:?}");
        }
        let own = sim
            .stream(imu)
            .take_while(|m| m.stamp_ns() <= 20_000_000_000)
            .count();
        assert_eq!(n, own, "the healthy worker got its whole stream");
        // At most one stall each (whether their waits overlap depends on how their pipes
        // filled); the simulation itself takes milliseconds.
        eprintln!("the healthy worker had its stream after {took:?} (stall {stall:?})");
        assert!(
            took < stall * 4,
            "the healthy worker waited {took:?}: the group waited for its hung workers"
        );
    }
}
