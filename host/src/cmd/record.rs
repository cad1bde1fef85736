//! `vinebench record`: simulate a scenario and write its sensor stream as an MCAP file of
//! ROS 2 messages (see [`crate::dataset`] for topics, frames and time).

use std::collections::BTreeMap;
use std::path::PathBuf;
use std::time::Instant;

use anyhow::Context as _;
use clap::Args;
use indicatif::{ProgressBar, ProgressStyle};
use sim::SensorSet;

use crate::cmd::sim_args::{SimArgs, Simulated};
use crate::dataset::{EPOCH_NS, Recorder};

#[derive(Debug, Args)]
pub struct RecordArgs {
    #[command(flatten)]
    pub sim: SimArgs,
    /// The MCAP file to write (replaced if it exists; written under a temporary name first).
    #[arg(short = 'o', long = "output", value_name = "FILE.mcap")]
    pub output: PathBuf,
    /// Sensors to record: any of gt,imu,odom,lidar,scan2d,rgbd,gnss, or all. The camera (rgbd)
    /// is left out by default: it adds about 64 MB per simulated second.
    #[arg(long, default_value = "gt,imu,odom,lidar,scan2d")]
    pub sensors: String,
}

/// What made the recording, stored as its `vinebench` metadata record.
fn metadata(args: &RecordArgs) -> anyhow::Result<BTreeMap<String, String>> {
    let world = match (&args.sim.world, args.sim.profile) {
        // Under another profile: the world as it was resolved.
        (world, Some(profile)) => {
            sim::SimConfig::load_as(world.as_deref(), Some(profile))?.to_toml_string()
        }
        (Some(p), None) => std::fs::read_to_string(p).with_context(|| p.display().to_string())?,
        (None, None) => sim::DEFAULT_CONFIG_TOML.to_owned(),
    };
    Ok(BTreeMap::from([
        ("scenario".to_owned(), args.sim.scenario.clone()),
        ("seed".to_owned(), args.sim.seed.to_string()),
        ("sensors".to_owned(), args.sensors.clone()),
        (
            "max_time_s".to_owned(),
            args.sim
                .max_time
                .map_or("none".to_owned(), |t| t.to_string()),
        ),
        ("epoch_ns".to_owned(), EPOCH_NS.to_string()),
        ("world_toml".to_owned(), world),
        (
            "vinebench_version".to_owned(),
            env!("CARGO_PKG_VERSION").to_owned(),
        ),
    ]))
}

pub fn run(args: &RecordArgs) -> anyhow::Result<()> {
    let started = Instant::now();
    let sensors: SensorSet = args
        .sensors
        .parse()
        .map_err(|e: String| anyhow::anyhow!("--sensors {}: {e}", args.sensors))?;
    let Simulated {
        config,
        sim,
        end_ns: duration_ns,
    } = args.sim.simulate()?;
    let mut recorder = Recorder::create(&args.output, &config, sensors, metadata(args)?)?;
    let bar = ProgressBar::new(duration_ns as u64 / 1_000_000);
    bar.set_style(
        ProgressStyle::with_template("{prefix} [{bar:40}] {pos}/{len} ms simulated ({eta})")
            .expect("valid template")
            .progress_chars("=> "),
    );
    bar.set_prefix(format!("record {}", args.sim.scenario));
    let mut counts = BTreeMap::<&'static str, u64>::new();
    for message in sim
        .stream(sensors)
        .take_while(|m| m.stamp_ns() <= duration_ns)
    {
        *counts.entry(message.sensor()).or_default() += 1;
        bar.set_position(message.stamp_ns().max(0) as u64 / 1_000_000);
        recorder.write(&message)?;
    }
    bar.finish_and_clear();
    let bytes = recorder.finish()?;
    let wall = started.elapsed().as_secs_f64();
    let simulated = duration_ns as f64 * 1e-9;
    let summary: Vec<String> = counts.iter().map(|(k, v)| format!("{k} {v}")).collect();
    crate::out!(
        "wrote {} ({:.1} MB): {simulated:.1} s of {}; messages: {}",
        args.output.display(),
        bytes as f64 / 1e6,
        args.sim.scenario,
        summary.join(", ")
    );
    crate::out!("wall time: {wall:.2} s");
    crate::out!("real-time factor: {:.2}", simulated / wall);
    Ok(())
}
