//! `vinebench simulate`: drive a scenario, stream the selected sensors, optionally dump them,
//! and report the real-time factor and what each sensor costs.

use std::path::PathBuf;
use std::time::Instant;

use anyhow::Context as _;
use clap::Args;
use indicatif::{ProgressBar, ProgressStyle};
use sim::SensorSet;

use crate::cmd::sim_args::{SimArgs, Simulated};
use crate::dump::Dump;
use crate::runner::timing::SimulationCost;

#[derive(Debug, Args)]
pub struct SimulateArgs {
    #[command(flatten)]
    pub sim: SimArgs,
    /// Sensors to simulate: any of gt,imu,odom,lidar,scan2d,rgbd, or all.
    #[arg(long, default_value = "all")]
    pub sensors: String,
    /// Write the data here: ground truth TUM, lidar KITTI .bin + times.txt, camera as TUM
    /// RGB-D (rgbd/), CSVs, top view.
    #[arg(long)]
    pub out: Option<PathBuf>,
}

pub fn run(args: &SimulateArgs) -> anyhow::Result<()> {
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
    let mut dump = match &args.out {
        Some(dir) => Some(
            Dump::create(dir, &sim, &config)
                .with_context(|| format!("cannot write to {}", dir.display()))?,
        ),
        None => None,
    };

    let bar = ProgressBar::new(duration_ns as u64 / 1_000_000);
    bar.set_style(
        ProgressStyle::with_template(
            "{prefix} [{bar:40}] {pos}/{len} ms simulated, {per_sec} ({eta})",
        )
        .expect("valid template")
        .progress_chars("=> "),
    );
    bar.set_prefix(format!("simulate {}", args.sim.scenario));
    let mut counts = std::collections::BTreeMap::<&'static str, u64>::new();
    // Wall time spent making each sensor's messages, and writing them with --out.
    let mut making = SimulationCost::default();
    let mut writing = std::collections::BTreeMap::<&'static str, f64>::new();
    let mut lidar_points = 0u64;
    let mut stream = sim.stream(sensors);
    while let Some(message) = making.next_from(&mut stream) {
        if message.stamp_ns() > duration_ns {
            break;
        }
        *counts.entry(message.sensor()).or_default() += 1;
        if let sim::sensors::Message::Lidar(scan) = &message {
            lidar_points += scan.points.len() as u64;
        }
        bar.set_position(message.stamp_ns().max(0) as u64 / 1_000_000);
        if let Some(d) = dump.as_mut() {
            let written = Instant::now();
            d.write(&message)?;
            *writing.entry(message.sensor()).or_default() += written.elapsed().as_secs_f64();
        }
    }
    bar.finish_and_clear();
    // Whatever the PNG writer still has in hand is the camera's writing too.
    let finishing = Instant::now();
    if let Some(d) = dump {
        let dir = d.finish()?;
        *writing.entry("rgbd").or_default() += finishing.elapsed().as_secs_f64();
        eprintln!("wrote {}", dir.display());
    }
    let wall = started.elapsed().as_secs_f64();
    let simulated = duration_ns as f64 * 1e-9;
    let summary: Vec<String> = counts.iter().map(|(k, v)| format!("{k} {v}")).collect();
    crate::out!(
        "scenario {}: {:.1} m in {simulated:.1} s simulated; messages: {}; lidar points {lidar_points}",
        args.sim.scenario,
        crate::dump::path_length(&sim),
        summary.join(", ")
    );
    // What each sensor of the rig costs: wall seconds per simulated second to make its
    // messages (and to write them), the simulator's parallel work included.
    let per_sensor: Vec<String> = making
        .per_simulated_s(simulated)
        .iter()
        .map(|(sensor, make)| match writing.get(sensor.as_str()) {
            Some(write) if args.out.is_some() => {
                format!("{sensor} {make:.3} + {:.3} writing", write / simulated)
            }
            _ => format!("{sensor} {make:.3}"),
        })
        .collect();
    crate::out!("cost, wall s per simulated s: {}", per_sensor.join(", "));
    crate::out!("wall time: {wall:.2} s");
    crate::out!("real-time factor: {:.2}", simulated / wall);
    Ok(())
}
