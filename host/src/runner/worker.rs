//! The worker process: simulates one scenario, feeds the plugin in time order (the simulator
//! produces ahead on its own thread), records every pose the plugin returns and how long
//! each call took, and writes the run's files. Anything the plugin does wrong ends this
//! process only.

use std::io::Write;
use std::path::Path;
use std::sync::mpsc::sync_channel;
use std::time::Instant;

use anyhow::{Context as _, anyhow, bail};
use eval::Trajectory;
use nalgebra::Isometry3;
use plugin_api::{LaserScan, LidarPoint, PluginInstance, Pose, SensorKind, SlamOutput};
use sim::sensors::Message;
use sim::{SensorSet, Simulation};

use super::feed::{AHEAD, FeedReader};
use super::job::{Job, Pace};
use super::timing::{SimulationCost, Timing, process_cpu_s, process_peak_rss_mb};
use crate::results::{RunFolder, files};

/// Which sensors to simulate for a plugin's requirements (ground truth always).
pub fn sensor_set(kinds: &[SensorKind]) -> SensorSet {
    let mut set = SensorSet {
        ground_truth: true,
        ..SensorSet::default()
    };
    for kind in kinds {
        match kind {
            SensorKind::Imu => set.imu = true,
            SensorKind::WheelOdometry => set.wheel_odometry = true,
            SensorKind::Lidar => set.lidar = true,
            SensorKind::Scan2d => set.scan2d = true,
            SensorKind::Rgbd => set.rgbd = true,
            SensorKind::Gnss => set.gnss = true,
        }
    }
    set
}

/// Holds messages back to simulated time under [`Pace::Realtime`]; does nothing under
/// [`Pace::Free`].
#[derive(Debug)]
struct Pacer {
    pace: Pace,
    /// The wall-clock instant and stamp of the first message.
    start: Option<(Instant, i64)>,
}

impl Pacer {
    fn new(pace: Pace) -> Self {
        Self { pace, start: None }
    }

    /// Whether `stamp_ns` is due by now (never before the first message, never on a free
    /// run).
    fn is_due(&self, stamp_ns: i64) -> bool {
        match (self.pace, self.start) {
            (Pace::Realtime, Some((t0, first))) => {
                t0 + std::time::Duration::from_nanos(stamp_ns.saturating_sub(first).max(0) as u64)
                    <= Instant::now()
            }
            _ => false,
        }
    }

    /// Sleeps until `stamp_ns` is due: its distance from the first stamp, on the wall clock
    /// since the first message.
    fn wait_for(&mut self, stamp_ns: i64) {
        if self.pace == Pace::Free {
            return;
        }
        let (t0, first) = *self.start.get_or_insert((Instant::now(), stamp_ns));
        let due =
            t0 + std::time::Duration::from_nanos(stamp_ns.saturating_sub(first).max(0) as u64);
        let now = Instant::now();
        if due > now {
            std::thread::sleep(due - now);
        }
    }
}

/// Runs the job; an error is the run's failure reason.
pub fn work(job: &Job) -> anyhow::Result<()> {
    let limit = job.memory_limit_mb.saturating_mul(1 << 20);
    rlimit::setrlimit(rlimit::Resource::AS, limit, limit).context("cannot set the memory limit")?;
    let started = Instant::now();
    let config = sim::SimConfig::load(job.world.as_deref())?;
    let plugin = plugin_api::load(&job.plugin)?;
    let requirements = plugin
        .requirements_for(&job.params_toml)
        .map_err(|e| anyhow!("plugin {}: {e}", plugin.name))?;
    let sensors = sensor_set(&requirements.sensors);
    let sim = Simulation::new(&config, &job.scenario, job.seed)?;
    let rig = crate::rig::rig_for(&config, &requirements.sensors);
    write_run_toml(job, &config, &plugin, &requirements)?;
    write_placed(job, &config, &sim)?;
    let mut instance = match &job.localize {
        None => plugin
            .create(&job.params_toml, &rig)
            .map_err(|e| anyhow!("plugin {} failed to start: {e}", plugin.name))?,
        Some(spec) => {
            let (map, format, version) =
                super::localize::map_bytes(spec, &plugin.name, &config, sim.scene().world)?;
            let start = plugin_api::MapStart {
                map: &map,
                format: &format,
                format_version: version,
                initial_guess: spec.initial_guess(),
            };
            let loading = Instant::now();
            let instance = plugin
                .create_localizing(&job.params_toml, &rig, &start)
                .map_err(|e| {
                    let from = match &spec.map {
                        super::MapSource::Saved { path } => path.display().to_string(),
                        super::MapSource::Grid { yaml } => yaml.display().to_string(),
                        super::MapSource::Surveyed { world: None } => {
                            "the surveyed grid".to_owned()
                        }
                        super::MapSource::Surveyed { world: Some(w) } => {
                            format!("the surveyed grid of {}", w.display())
                        }
                    };
                    anyhow!("{from}: plugin {} cannot localise in it: {e}", plugin.name)
                })?;
            write_localization(job, spec, map.len(), loading.elapsed().as_secs_f64())?;
            instance
        }
    };
    let mut statuses = Vec::new();

    let total_ns = super::job::route_end_ns(sim.duration_ns(), job.max_time_s)?;
    let mut groundtruth = Vec::new();
    let mut online = Vec::new();
    let mut timing = Timing::default();
    let mut points = Vec::new();
    let mut next_progress = 0;
    let mut stdout = std::io::stdout().lock();
    // Replay is checked whole before anything is fed, so a bad file fails the run cleanly.
    // A shared simulation's stream is checked as it comes: its error fails the run below.
    let mut feed_error = None;
    let source: Box<dyn Iterator<Item = Message> + Send + '_> = match (&job.dataset, job.fed) {
        // A recording made once for the runs of every receiver leaves GNSS out
        // (`runner::record`): this run's own receiver is simulated here, from its own world,
        // and its epochs merged in where the live stream puts them.
        (Some(path), _) if job.recorded && sensors.gnss && !config.sensors.gnss.is_absent() => {
            let recorded = SensorSet {
                gnss: false,
                ..sensors
            };
            let live = sim.stream(SensorSet {
                gnss: true,
                ..SensorSet::default()
            });
            Box::new(crate::dataset::replay_with_live(path, recorded, live)?)
        }
        (Some(path), _) => Box::new(crate::dataset::replay_messages(path, sensors)?),
        (None, true) => {
            let reader = FeedReader::new(std::io::stdin());
            feed_error = Some(reader.error_slot());
            Box::new(reader)
        }
        (None, false) => Box::new(sim.stream(sensors)),
    };
    // The stream is in time order: a route limit cuts it, as `simulate --max-time` does.
    // Without one the stream is fed whole, as before.
    let cut = job.max_time_s.is_some();
    let kidnap = job.localize.as_ref().and_then(|l| l.kidnap);
    let source = super::localize::kidnapped(source, kidnap)
        .take_while(move |m| !cut || m.stamp_ns() <= total_ns);
    if let Some(q) = &job.queue_size {
        q.check(job.pace).map_err(|why| anyhow!("{why}"))?;
    }
    let given = job
        .drops
        .as_deref()
        .map(super::queue::read_drops)
        .transpose()?;
    let mut queues = super::queue::Queues::new(job.queue_size.clone(), given);
    let mut gnss_epochs: Vec<(i64, sim::sensors::gnss::FixStatus)> = Vec::new();
    let cost = std::thread::scope(|scope| -> anyhow::Result<SimulationCost> {
        let (tx, rx) = sync_channel(AHEAD);
        let producer = scope.spawn(move || {
            let mut cost = SimulationCost::default();
            let mut source = source;
            while let Some(message) = cost.next_from(&mut source) {
                if tx.send(message).is_err() {
                    break;
                }
            }
            cost
        });
        let mut clock = Pacer::new(job.pace);
        // With bounded queues on a paced run, what has arrived by the time the system is free
        // waits in its topic's queue (and a full one drops); otherwise each message is taken
        // from the stream when the system is ready for it, as before.
        let eager = job.queue_size.is_some() && job.pace == Pace::Realtime;
        let mut rx = rx.into_iter().peekable();
        loop {
            while let Some(m) = rx.next_if(|m| {
                matches!(m, Message::GroundTruth(_)) || (eager && clock.is_due(m.stamp_ns()))
            }) {
                match m {
                    Message::GroundTruth(gt) => {
                        groundtruth.push(Pose::new(gt.stamp_ns, &gt.world_from_base));
                    }
                    m => queues.push(m),
                }
            }
            let message = match queues.pop() {
                Some(m) => m,
                None => match rx.next() {
                    None => break,
                    Some(Message::GroundTruth(gt)) => {
                        groundtruth.push(Pose::new(gt.stamp_ns, &gt.world_from_base));
                        continue;
                    }
                    Some(m) => {
                        clock.wait_for(m.stamp_ns());
                        queues.push(m);
                        continue;
                    }
                },
            };
            let stamp = message.stamp_ns();
            if let Message::Gnss(g) = &message {
                gnss_epochs.push((g.stamp_ns, g.status));
            }
            let call = Instant::now();
            let returned = deliver(&mut instance, &message, &mut points).map_err(|e| {
                anyhow!(
                    "plugin {} failed at t = {:.3} s: {e}",
                    plugin.name,
                    stamp as f64 * 1e-9
                )
            })?;
            timing.record(message.sensor(), call.elapsed());
            if let Some(pose) = returned {
                check(&pose, "online pose")?;
                online.push(pose);
                statuses.push(instance.status());
            }
            if stamp >= next_progress {
                writeln!(stdout, "progress {stamp} {total_ns}").ok();
                stdout.flush().ok();
                next_progress = stamp + total_ns / 100;
            }
        }
        producer
            .join()
            .map_err(|_| anyhow!("the simulator thread panicked"))
    })?;
    if let Some(slot) = feed_error
        && let Some(e) = slot.lock().expect("no panic holds this lock").take()
    {
        bail!("{e}");
    }
    let call = Instant::now();
    let output = instance
        .finish()
        .map_err(|e| anyhow!("plugin {} failed in finish: {e}", plugin.name))?;
    timing.record("finish", call.elapsed());
    if output.trajectory.is_empty() {
        bail!("plugin {} returned an empty trajectory", plugin.name);
    }
    for pose in &output.trajectory {
        check(pose, "final pose")?;
    }
    if let Some(grid) = &output.grid
        && grid.cells.len() != grid.width as usize * grid.height as usize
    {
        bail!(
            "plugin {} returned a {}x{} grid with {} cells",
            plugin.name,
            grid.width,
            grid.height,
            grid.cells.len()
        );
    }
    write_outputs(&job.out_dir, &groundtruth, &online, &output)?;
    if !gnss_epochs.is_empty() {
        let mut text = String::from("stamp_ns,status\n");
        for (t, status) in &gnss_epochs {
            text += &format!("{t},{}\n", status.name());
        }
        std::fs::write(job.out_dir.join(files::GNSS), text)
            .with_context(|| job.out_dir.join(files::GNSS).display().to_string())?;
    }
    if let Some(saved) = &output.saved_map {
        crate::results::map_file::write_map(
            &job.out_dir.join(files::SAVED_MAP),
            &plugin.name,
            &plugin.version,
            saved,
        )?;
    }
    if job.localize.is_some() {
        let stamps: Vec<i64> = online.iter().map(|p| p.stamp_ns).collect();
        super::localize::write_statuses(&job.out_dir, &stamps, &statuses)?;
    }
    let wall = started.elapsed().as_secs_f64();
    // The simulated time fed: the route up to its limit.
    let simulated = total_ns as f64 * 1e-9;
    let mut report = timing.report(simulated, wall, process_cpu_s(), process_peak_rss_mb());
    report.dropped = queues.counts();
    if job.queue_size.is_some() || job.drops.is_some() {
        std::fs::write(job.out_dir.join(files::DROPPED), queues.csv())
            .with_context(|| job.out_dir.join(files::DROPPED).display().to_string())?;
    }
    report.source = match (&job.dataset, job.fed) {
        (Some(_), _) if job.recorded => "recording",
        (Some(_), _) => "dataset",
        (None, true) => "shared simulation",
        (None, false) => "simulation",
    }
    .to_owned();
    // Only the worker's own simulation costs it what the stream took; a shared one's cost
    // is the supervisor's to note (`runner::feed`), a dataset's is reading.
    if job.dataset.is_none() && !job.fed {
        report.simulation_cost = cost.per_simulated_s(simulated);
    }
    RunFolder::new(&job.out_dir).write_timing(&report)?;
    writeln!(stdout, "progress {total_ns} {total_ns}").ok();
    Ok(())
}

/// A simulated lidar point as plugins receive it.
pub fn plugin_point(p: &sim::sensors::LidarPoint) -> LidarPoint {
    LidarPoint {
        x: p.x,
        y: p.y,
        z: p.z,
        intensity: p.intensity,
        time_s: p.time_s,
        ring: p.ring,
    }
}

/// A simulated GNSS epoch as plugins receive it: without a fix, NaN position and zero
/// covariance.
pub fn plugin_gnss(g: &sim::sensors::gnss::GnssFix) -> plugin_api::Gnss {
    use sim::sensors::gnss::FixStatus;
    let [ve, vn, vu] = g.variance_enu_m2;
    let [lat, lon, alt] = g.geodetic.unwrap_or([f64::NAN; 3]);
    plugin_api::Gnss {
        stamp_ns: g.stamp_ns,
        status: match g.status {
            FixStatus::None => plugin_api::GnssStatus::NoFix,
            FixStatus::Single => plugin_api::GnssStatus::Single,
            FixStatus::Float => plugin_api::GnssStatus::Float,
            FixStatus::Fixed => plugin_api::GnssStatus::Fixed,
        },
        satellites: g.satellites as u32,
        position_enu_m: g.position_enu_m.map_or([f64::NAN; 3], Into::into),
        covariance_enu_m2: [ve, 0.0, 0.0, 0.0, vn, 0.0, 0.0, 0.0, vu],
        latitude_deg: lat,
        longitude_deg: lon,
        altitude_m: alt,
        hdop: g.hdop.unwrap_or(f64::NAN),
    }
}

/// A pose must be finite with a unit quaternion: an invalid one fails the run, it is
/// never evaluated.
fn check(pose: &Pose, what: &str) -> anyhow::Result<()> {
    if pose.isometry().is_none() {
        bail!(
            "the plugin returned an invalid {what} (NaN, infinite or non-unit quaternion) at t = {:.3} s",
            pose.stamp_ns as f64 * 1e-9
        );
    }
    Ok(())
}

/// Hands one simulator message to the plugin.
pub(crate) fn deliver(
    instance: &mut PluginInstance,
    message: &Message,
    points: &mut Vec<LidarPoint>,
) -> Result<Option<Pose>, plugin_api::PluginError> {
    match message {
        Message::GroundTruth(_) => Ok(None),
        Message::Imu(m) => instance.on_imu(&plugin_api::Imu {
            stamp_ns: m.stamp_ns,
            accel_mps2: m.accel_mps2.into(),
            gyro_rps: m.gyro_rps.into(),
            orientation_xyzw: m.orientation.map_or([0.0; 4], |q| [q.i, q.j, q.k, q.w]),
        }),
        Message::WheelOdometry(m) => instance.on_wheel_odometry(&plugin_api::WheelOdometry {
            stamp_ns: m.stamp_ns,
            linear_mps: m.linear_mps,
            angular_rps: m.angular_rps,
            odom_from_base: Pose::new(m.stamp_ns, &m.odom_from_base),
        }),
        Message::Lidar(scan) => {
            points.clear();
            points.extend(scan.points.iter().map(plugin_point));
            instance.on_point_cloud(&plugin_api::PointCloud {
                stamp_ns: scan.stamp_ns,
                sensor: "lidar",
                points,
            })
        }
        Message::Rgbd(f) => instance.on_rgbd(&plugin_api::RgbdFrame {
            stamp_ns: f.stamp_ns,
            sensor: "camera",
            width: f.image.width as u32,
            height: f.image.height as u32,
            rgb: &f.image.rgb,
            depth_m: &f.image.depth_m,
            intrinsics: f.image.intrinsics,
        }),
        Message::Gnss(g) => instance.on_gnss(&plugin_gnss(g)),
        Message::Scan2d(s) => instance.on_laser_scan(&LaserScan {
            stamp_ns: s.stamp_ns,
            sensor: s.side.name(),
            angle_min_rad: s.angle_min_rad,
            angle_increment_rad: s.angle_increment_rad,
            time_increment_s: s.time_increment_s,
            range_min_m: s.range_min_m,
            range_max_m: s.range_max_m,
            ranges_m: &s.ranges_m,
            intensities: &s.intensities,
        }),
    }
}

fn trajectory(poses: &[Pose]) -> Trajectory {
    Trajectory {
        stamps: poses.iter().map(|p| p.stamp_ns as f64 * 1e-9).collect(),
        poses: poses
            .iter()
            .map(|p| p.isometry().unwrap_or_else(Isometry3::identity))
            .collect(),
    }
}

fn write_outputs(
    dir: &Path,
    groundtruth: &[Pose],
    online: &[Pose],
    output: &SlamOutput,
) -> anyhow::Result<()> {
    eval::write_tum(dir.join(files::GROUNDTRUTH), &trajectory(groundtruth))?;
    eval::write_tum(dir.join(files::ESTIMATE), &trajectory(&output.trajectory))?;
    if !online.is_empty() {
        eval::write_tum(dir.join(files::ONLINE), &trajectory(online))?;
    }
    if let Some(map) = &output.map {
        crate::results::write_ply(&dir.join(files::MAP), map)?;
    }
    if let Some(grid) = &output.grid {
        crate::results::write_grid(&dir.join(files::GRID), &dir.join(files::GRID_YAML), grid)?;
    }
    RunFolder::new(dir).write_events(&output.events)?;
    Ok(())
}

/// run.toml: everything that determined this run, resolved.
fn write_run_toml(
    job: &Job,
    config: &sim::SimConfig,
    plugin: &plugin_api::LoadedPlugin,
    requirements: &plugin_api::Requirements,
) -> anyhow::Result<()> {
    let mut doc = toml::Table::new();
    let mut put = |k: &str, v: toml::Value| {
        doc.insert(k.to_owned(), v);
    };
    put("scenario", job.scenario.clone().into());
    put("seed", toml::Value::Integer(job.seed as i64));
    put("world_seed", toml::Value::Integer(config.world_seed as i64));
    put(
        "world",
        job.world
            .as_ref()
            .map_or("configs/world.toml (embedded)".to_owned(), |p| {
                p.display().to_string()
            })
            .into(),
    );
    if let Some(s) = job.max_time_s {
        put("max_time_s", toml::Value::Float(s));
    }
    put("vinebench_version", env!("CARGO_PKG_VERSION").into());
    put("plugin_api_version", plugin_api::API_VERSION.into());
    let mut p = toml::Table::new();
    p.insert("name".into(), plugin.name.clone().into());
    p.insert("version".into(), plugin.version.clone().into());
    p.insert("path".into(), plugin.path.display().to_string().into());
    p.insert(
        "sensors".into(),
        toml::Value::Array(
            requirements
                .sensors
                .iter()
                .map(|k| toml::Value::from(k.name()))
                .collect(),
        ),
    );
    let params: toml::Table = toml::from_str(&job.params_toml).unwrap_or_default();
    p.insert("params".into(), toml::Value::Table(params));
    put("plugin", toml::Value::Table(p));
    let path = job.out_dir.join(files::RUN);
    std::fs::write(&path, toml::to_string(&doc)?).with_context(|| path.display().to_string())?;
    // The world as resolved, every key written out: `world` above names where it came from,
    // this is what it was.
    let path = job.out_dir.join(files::WORLD);
    std::fs::write(&path, config.to_toml_string()).with_context(|| path.display().to_string())
}

/// `localization.toml`: the run's order, with the map's size and how long the plugin took
/// to start from it.
fn write_localization(
    job: &Job,
    spec: &super::LocalizeSpec,
    map_bytes: usize,
    load_s: f64,
) -> anyhow::Result<()> {
    let mut doc = toml::Table::try_from(spec)?;
    doc.insert("map_bytes".into(), toml::Value::Integer(map_bytes as i64));
    doc.insert("load_s".into(), toml::Value::Float(load_s));
    let path = job.out_dir.join(files::LOCALIZATION);
    std::fs::write(&path, toml::to_string(&doc)?).with_context(|| path.display().to_string())
}

/// `placed.toml`: where each sensor with a `mount_error` really sat in this run.
fn write_placed(job: &Job, config: &sim::SimConfig, sim: &Simulation) -> anyhow::Result<()> {
    use sim::config::Side;
    let (told, placed) = (&config.sensors, sim.placed_sensors());
    let mounts = [
        ("imu", told.imu.mount, placed.imu.mount),
        ("lidar", told.lidar.mount, placed.lidar.mount),
        ("camera", told.camera.mount, placed.camera.mount),
        (
            "scan2d_front",
            told.scan2d_front.mount_for(Side::Front),
            placed.scan2d_front.mount_for(Side::Front),
        ),
        (
            "scan2d_back",
            told.scan2d_back.mount_for(Side::Back),
            placed.scan2d_back.mount_for(Side::Back),
        ),
    ];
    let mut doc = toml::Table::new();
    for (name, nominal, real) in mounts {
        if nominal != real {
            let mut t = toml::Table::new();
            t.insert("mount".into(), toml::Value::try_from(real)?);
            t.insert("nominal".into(), toml::Value::try_from(nominal)?);
            doc.insert(name.into(), toml::Value::Table(t));
        }
    }
    if doc.is_empty() {
        return Ok(());
    }
    let path = job.out_dir.join(files::PLACED);
    std::fs::write(&path, toml::to_string(&doc)?).with_context(|| path.display().to_string())
}
