//! `vinebench gnss-map`: how the world's GNSS receiver fares in the block, lane by lane
//! (issue 47's fix-quality maps). The robot drives every lane of the block in turn (a
//! serpentine, U-turns in the headlands) at each growth stage asked for, the receiver
//! measuring as in any run; each epoch is put in the lane (or the headland) its antenna
//! is over, and the command writes per lane the fraction of epochs of each fix status
//! (`gnss-map.csv`) and a top view of the route coloured by status per stage
//! (`gnss-map-stage<S>.svg`).
//!
//! The fraction is of time, as a robot driving the lanes meets it: after a blockage the
//! receiver refixes only after `rtk_fix_after_s`, so a lane's status depends on the lanes
//! driven before it, as it would in the field.

use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::path::PathBuf;

use anyhow::{Context as _, bail};
use clap::Args;
use nalgebra::Isometry3;
use sim::config::{Profile, RouteSpec};
use sim::sensors::Message;
use sim::sensors::gnss::FixStatus;
use sim::{SensorSet, SimConfig, Simulation};

use crate::cmd::sim_args::parse_profile;
use crate::report::figures::FIX_COLOURS;

#[derive(Debug, Args)]
pub struct GnssMapArgs {
    /// Simulator configuration with a receiver (`[sensors.gnss] profile = "rtk"` or
    /// "consumer"); a block of rows (`vineyard.rows`), not the paper world's segments.
    #[arg(long)]
    pub world: Option<PathBuf>,
    /// The sensors' models, whatever the world file's `profile` says.
    #[arg(long, value_parser = parse_profile)]
    pub profile: Option<Profile>,
    /// Seed of the receiver's sky and errors.
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// Growth stages to map, comma-separated (0 dormant .. 4 full canopy); default: the
    /// world's own.
    #[arg(long, value_delimiter = ',')]
    pub stages: Vec<f64>,
    /// Folder to write gnss-map.csv and one SVG per stage into.
    #[arg(long)]
    pub out: PathBuf,
}

/// Where an epoch's antenna was.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord)]
enum Place {
    Lane(usize),
    Headland,
}

/// Epochs of each status at one place.
#[derive(Debug, Default, Clone)]
struct Tally {
    by_status: BTreeMap<FixStatus, u64>,
    satellites: u64,
}

impl Tally {
    fn epochs(&self) -> u64 {
        self.by_status.values().sum()
    }

    fn fraction(&self, status: FixStatus) -> f64 {
        let n = self.epochs();
        if n == 0 {
            return 0.0;
        }
        *self.by_status.get(&status).unwrap_or(&0) as f64 / n as f64
    }
}

/// The statuses best first, with their colours on the map (the report's).
const STATUSES: [(FixStatus, &str); 4] = [
    (FixStatus::Fixed, FIX_COLOURS[0].1),
    (FixStatus::Float, FIX_COLOURS[1].1),
    (FixStatus::Single, FIX_COLOURS[2].1),
    (FixStatus::None, FIX_COLOURS[3].1),
];

pub fn run(args: &GnssMapArgs) -> anyhow::Result<()> {
    let base = SimConfig::load_as(args.world.as_deref(), args.profile)?;
    let world_name = args
        .world
        .as_ref()
        .map_or("the built-in world".to_owned(), |p| p.display().to_string());
    if base.sensors.gnss.is_absent() {
        bail!(
            "{world_name} has no GNSS receiver: set [sensors.gnss] profile = \"rtk\" or \"consumer\""
        );
    }
    if !base.vineyard.segments.is_empty() || base.vineyard.lanes() == 0 {
        bail!(
            "{world_name}: gnss-map drives the lanes of a block of rows (vineyard.rows, \
             row_spacing_m); a world of placed segments has no lanes to drive"
        );
    }
    let stages = if args.stages.is_empty() {
        vec![base.vineyard.growth_stage]
    } else {
        args.stages.clone()
    };
    std::fs::create_dir_all(&args.out).with_context(|| args.out.display().to_string())?;
    let mut csv =
        String::from("growth_stage,place,epochs,fixed,float,single,none,mean_satellites\n");
    for stage in stages {
        let mut config = base.clone();
        config.vineyard.growth_stage = stage;
        config
            .validate()
            .map_err(|e| anyhow::anyhow!("--stages {stage}: {e}"))?;
        let lanes = config.vineyard.lanes();
        config.scenarios.insert(
            "gnss-map".to_owned(),
            RouteSpec::Serpentine {
                first_lane: 0,
                lanes,
                overshoot_m: 3.47,
            },
        );
        let sim = Simulation::new(&config, "gnss-map", args.seed)?;
        let [x, y, z] = config.sensors.gnss.mount_xyz_m;
        let base_from_antenna = Isometry3::translation(x, y, z);
        let v = &config.vineyard;
        let place = |p: &nalgebra::Vector3<f64>| {
            let lane = (p.y / v.row_spacing_m).floor();
            if (0.0..=v.row_length_m).contains(&p.x) && lane >= 0.0 && (lane as usize) < lanes {
                Place::Lane(lane as usize)
            } else {
                Place::Headland
            }
        };
        let mut tallies: BTreeMap<Place, Tally> = BTreeMap::new();
        let mut track = Vec::new();
        let sensors = SensorSet {
            gnss: true,
            ..SensorSet::default()
        };
        for message in sim.stream(sensors) {
            let Message::Gnss(fix) = message else {
                continue;
            };
            let antenna = (sim.trajectory.pose(fix.stamp_ns) * base_from_antenna)
                .translation
                .vector;
            let tally = tallies.entry(place(&antenna)).or_default();
            *tally.by_status.entry(fix.status).or_insert(0) += 1;
            tally.satellites += fix.satellites as u64;
            track.push((antenna.x, antenna.y, fix.status));
        }
        let mut in_lanes = Tally::default();
        for (where_, tally) in &tallies {
            let name = match where_ {
                Place::Lane(k) => format!("lane {k}"),
                Place::Headland => "headland".to_owned(),
            };
            let mean_sats = tally.satellites as f64 / tally.epochs().max(1) as f64;
            write!(csv, "{stage},{name},{}", tally.epochs())?;
            for (status, ..) in STATUSES {
                write!(csv, ",{:.4}", tally.fraction(status))?;
            }
            writeln!(csv, ",{mean_sats:.2}")?;
            if matches!(where_, Place::Lane(_)) {
                for (s, n) in &tally.by_status {
                    *in_lanes.by_status.entry(*s).or_insert(0) += n;
                }
            }
        }
        let svg = args.out.join(format!("gnss-map-stage{stage}.svg"));
        std::fs::write(&svg, draw(&config, stage, &track))
            .with_context(|| svg.display().to_string())?;
        out!(
            "growth stage {stage}: in the lanes {} epochs, fixed {:.1} %, float {:.1} %, single {:.1} %, none {:.1} % -> {}",
            in_lanes.epochs(),
            100.0 * in_lanes.fraction(FixStatus::Fixed),
            100.0 * in_lanes.fraction(FixStatus::Float),
            100.0 * in_lanes.fraction(FixStatus::Single),
            100.0 * in_lanes.fraction(FixStatus::None),
            svg.display()
        );
    }
    let path = args.out.join("gnss-map.csv");
    std::fs::write(&path, csv).with_context(|| path.display().to_string())?;
    out!("wrote {}", path.display());
    Ok(())
}

/// A top view: the rows as grey lines, each epoch a dot coloured by its status.
fn draw(config: &SimConfig, stage: f64, track: &[(f64, f64, FixStatus)]) -> String {
    let v = &config.vineyard;
    let (mut lo, mut hi) = ([-4.0f64, -4.0f64], [v.row_length_m + 4.0, 0.0f64]);
    hi[1] = (v.rows.max(1) - 1) as f64 * v.row_spacing_m + 4.0;
    for &(x, y, _) in track {
        lo = [lo[0].min(x - 1.0), lo[1].min(y - 1.0)];
        hi = [hi[0].max(x + 1.0), hi[1].max(y + 1.0)];
    }
    let scale = 20.0;
    let (w, h) = ((hi[0] - lo[0]) * scale, (hi[1] - lo[1]) * scale);
    let px = |x: f64| (x - lo[0]) * scale;
    let py = |y: f64| (hi[1] - y) * scale;
    let mut s = format!(
        "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"{w:.0}\" height=\"{:.0}\" \
         font-family=\"sans-serif\" font-size=\"14\">\n<rect width=\"100%\" height=\"100%\" fill=\"white\"/>\n",
        h + 30.0
    );
    for r in 0..v.rows {
        let y = r as f64 * v.row_spacing_m;
        let _ = writeln!(
            s,
            "<line x1=\"{:.1}\" y1=\"{:.1}\" x2=\"{:.1}\" y2=\"{:.1}\" stroke=\"#999\" stroke-width=\"6\"/>",
            px(0.0),
            py(y),
            px(v.row_length_m),
            py(y)
        );
    }
    for &(x, y, status) in track {
        let colour = STATUSES
            .iter()
            .find(|(st, _)| *st == status)
            .map_or("#000", |(_, c)| c);
        let _ = writeln!(
            s,
            "<circle cx=\"{:.1}\" cy=\"{:.1}\" r=\"3\" fill=\"{colour}\"/>",
            px(x),
            py(y)
        );
    }
    let mut legend = format!("growth stage {stage}:");
    for (status, colour) in STATUSES {
        let name = status.name();
        let _ = write!(legend, " <tspan fill=\"{colour}\">● {name}</tspan>");
    }
    let _ = writeln!(
        s,
        "<text x=\"8\" y=\"{:.0}\">{legend}</text>\n</svg>",
        h + 22.0
    );
    s
}
