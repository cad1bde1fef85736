//! `vinebench export`: simulate a scenario and write ground truth and lidar in the formats
//! other tools read, with [`crate::dump::Dump`]'s writers: `groundtruth.tum` (TUM RGB-D
//! benchmark trajectory format: `t x y z qx qy qz qw`, world frame) and `lidar/NNNNNN.bin`
//! with `lidar/times.txt` (KITTI odometry velodyne format: x, y, z, reflectance as
//! little-endian f32, sensor frame; one sweep start time per line), plus `topview.png`.

use std::path::PathBuf;
use std::time::Instant;

use anyhow::Context as _;
use clap::Args;
use sim::{SensorSet, Simulation};

use crate::dump::Dump;

#[derive(Debug, Args)]
#[command(
    after_help = "TUM RGB-D sequences (rgb/, depth/, associations) come with the RGB-D camera, \
                  which the simulator does not have yet."
)]
pub struct ExportArgs {
    /// Scenario: s0, s1, s2, s3 or a route named in the world file.
    #[arg(long)]
    pub scenario: String,
    /// Folder to write: groundtruth.tum (TUM), lidar/*.bin + lidar/times.txt (KITTI).
    #[arg(long)]
    pub out: PathBuf,
    /// Simulator configuration (configs/world.toml shape); defaults are built in.
    #[arg(long)]
    pub world: Option<PathBuf>,
    /// Seed of all sensor noise.
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// Stop after this many simulated seconds (default: the whole route).
    #[arg(long, value_name = "SECONDS")]
    pub max_time: Option<f64>,
}

pub fn run(args: &ExportArgs) -> anyhow::Result<()> {
    let started = Instant::now();
    let config = sim::SimConfig::load(args.world.as_deref())?;
    let sim = Simulation::new(&config, &args.scenario, args.seed)?;
    let duration_ns = match args.max_time {
        Some(s) if s.is_finite() && s > 0.0 => sim.duration_ns().min((s * 1e9) as i64),
        Some(s) => anyhow::bail!("--max-time {s}: must be a positive number of seconds"),
        None => sim.duration_ns(),
    };
    let sensors = SensorSet {
        ground_truth: true,
        lidar: true,
        ..SensorSet::default()
    };
    let mut dump = Dump::create(&args.out, &sim)
        .with_context(|| format!("cannot write to {}", args.out.display()))?;
    let mut sweeps = 0u64;
    for message in sim
        .stream(sensors)
        .take_while(|m| m.stamp_ns() <= duration_ns)
    {
        sweeps += u64::from(matches!(message, sim::sensors::Message::Lidar(_)));
        dump.write(&message)?;
    }
    let dir = dump.finish()?;
    println!(
        "wrote {}: groundtruth.tum, {sweeps} lidar sweeps in lidar/ ({:.2} s)",
        dir.display(),
        started.elapsed().as_secs_f64()
    );
    Ok(())
}
