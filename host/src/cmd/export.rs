//! `vinebench export`: simulate a scenario and write it in the formats other tools read, with
//! [`crate::dump::Dump`]'s writers:
//! - `groundtruth.tum`: the base's pose (TUM RGB-D benchmark trajectory format,
//!   `t x y z qx qy qz qw`, world frame);
//! - `rgbd/`: the camera as a TUM RGB-D sequence (Sturm et al., IROS 2012): `rgb/<t>.png`,
//!   `depth/<t>.png` (16-bit, metres × 5000), `rgb.txt`, `depth.txt`, `associations.txt`, and
//!   `camera.yaml` with the intrinsics (ORB-SLAM2/3's RGB-D settings keys) and the camera's
//!   mount;
//! - `lidar/NNNNNN.bin` with `lidar/times.txt` (KITTI odometry velodyne format: x, y, z,
//!   reflectance as little-endian f32, sensor frame; one sweep start time per line);
//! - `gnss.csv`: the GNSS receiver's epochs (where the world has one): status,
//!   satellites, the antenna's east-north-up position in the world frame and its variances,
//!   WGS-84 latitude, longitude and height, HDOP;
//! - `topview.png`.

use std::path::PathBuf;
use std::time::Instant;

use anyhow::Context as _;
use clap::Args;
use sim::SensorSet;

use crate::cmd::sim_args::{SimArgs, Simulated};
use crate::dump::Dump;

#[derive(Debug, Args)]
pub struct ExportArgs {
    #[command(flatten)]
    pub sim: SimArgs,
    /// Folder to write: groundtruth.tum (TUM), rgbd/ (TUM RGB-D), lidar/*.bin +
    /// lidar/times.txt (KITTI).
    #[arg(long)]
    pub out: PathBuf,
    /// Sensors to export: any of gt,lidar,rgbd,gnss (ground truth always). The camera costs
    /// about the route's time to render and 2 MB per frame on disk.
    #[arg(long, default_value = "gt,lidar,rgbd")]
    pub sensors: String,
}

pub fn run(args: &ExportArgs) -> anyhow::Result<()> {
    let started = Instant::now();
    let chosen: SensorSet = args
        .sensors
        .parse()
        .map_err(|e: String| anyhow::anyhow!("--sensors {}: {e}", args.sensors))?;
    anyhow::ensure!(
        !(chosen.imu || chosen.wheel_odometry || chosen.scan2d),
        "--sensors {}: export writes gt, lidar, rgbd and gnss (simulate --out writes the others as CSV)",
        args.sensors
    );
    let sensors = SensorSet {
        ground_truth: true,
        ..chosen
    };
    let Simulated {
        config,
        sim,
        end_ns,
    } = args.sim.simulate()?;
    let mut dump = Dump::create(&args.out, &sim, &config)
        .with_context(|| format!("cannot write to {}", args.out.display()))?;
    let (mut sweeps, mut frames) = (0u64, 0u64);
    for message in sim.stream(sensors).take_while(|m| m.stamp_ns() <= end_ns) {
        sweeps += u64::from(matches!(message, sim::sensors::Message::Lidar(_)));
        frames += u64::from(matches!(message, sim::sensors::Message::Rgbd(_)));
        dump.write(&message)?;
    }
    let dir = dump.finish()?;
    crate::out!(
        "wrote {}: groundtruth.tum, {frames} RGB-D frames in rgbd/, {sweeps} lidar sweeps in lidar/ ({:.2} s)",
        dir.display(),
        started.elapsed().as_secs_f64()
    );
    Ok(())
}
