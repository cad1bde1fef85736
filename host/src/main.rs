use std::io::Write as _;

use clap::{Parser, Subcommand};

/// Benchmark SLAM systems in a simulated vineyard.
#[derive(Debug, Parser)]
#[command(name = "vinebench", version, about)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Debug, Subcommand)]
enum Command {
    /// Print the world a run would see, every key resolved (defaults, profile, file).
    World(vinebench::cmd::world::WorldArgs),
    /// Run the simulator along a scenario and optionally dump its sensor data.
    Simulate(vinebench::cmd::simulate::SimulateArgs),
    /// Record the simulated sensor stream as an MCAP file of ROS 2 messages.
    Record(vinebench::cmd::record::RecordArgs),
    /// Export ground truth (TUM) and lidar sweeps (KITTI) for other tools.
    Export(vinebench::cmd::export::ExportArgs),
    /// Map the GNSS receiver's fix quality along every lane of the block, per growth stage.
    GnssMap(vinebench::cmd::gnss_map::GnssMapArgs),
    /// Evaluate an estimated trajectory against ground truth (APE / RPE, as evo does).
    Eval(vinebench::cmd::eval::EvalArgs),
    /// Run one plugin on one scenario and score it.
    Run(vinebench::cmd::run::RunArgs),
    /// Start a plugin from a map built earlier and judge its localisation.
    Localize(vinebench::cmd::localize::LocalizeArgs),
    /// Run a matrix of scenarios x plugins and write the paper's table.
    Bench(vinebench::cmd::bench::BenchArgs),
    /// Run a sweep (a bench file plus seeds and world axes), resumable, here or on Slurm.
    Sweep(vinebench::cmd::sweep::SweepArgs),
    /// Rebuild report.html of a bench's or a sweep's results folder.
    Report(vinebench::cmd::report::ReportArgs),
    /// Score finished runs again with this build's evaluation, from what each run kept.
    Rescore(vinebench::cmd::rescore::RescoreArgs),
    /// List the plugins on the search path, and the libraries there that fail to load.
    Plugins(vinebench::cmd::plugins::PluginsArgs),
    /// Check that a plugin keeps the plugin contract: loads, runs a short route, and answers
    /// malformed and edge-case input without crashing, hanging or a non-finite pose.
    CheckPlugin(vinebench::cmd::check_plugin::CheckPluginArgs),
    /// One run in its own process (started by run and bench).
    #[command(hide = true)]
    Worker(vinebench::cmd::worker::WorkerArgs),
    /// One run of a Slurm sweep (started by sbatch).
    #[command(hide = true)]
    SweepTask(vinebench::cmd::sweep::SweepTaskArgs),
}

fn main() -> std::process::ExitCode {
    let cli = Cli::parse();
    let result = match cli.command {
        Command::World(args) => vinebench::cmd::world::run(&args),
        Command::Simulate(args) => vinebench::cmd::simulate::run(&args),
        Command::Record(args) => vinebench::cmd::record::run(&args),
        Command::Export(args) => vinebench::cmd::export::run(&args),
        Command::GnssMap(args) => vinebench::cmd::gnss_map::run(&args),
        Command::Eval(args) => vinebench::cmd::eval::run(&args),
        Command::Run(args) => vinebench::cmd::run::run(&args),
        Command::Localize(args) => vinebench::cmd::localize::run(&args),
        Command::Bench(args) => vinebench::cmd::bench::run(&args),
        Command::Sweep(args) => vinebench::cmd::sweep::run(&args),
        Command::SweepTask(args) => vinebench::cmd::sweep::run_task(&args),
        Command::Report(args) => vinebench::cmd::report::run(&args),
        Command::Rescore(args) => vinebench::cmd::rescore::run(&args),
        Command::Plugins(args) => vinebench::cmd::plugins::run(&args),
        Command::CheckPlugin(args) => vinebench::cmd::check_plugin::run(&args),
        Command::Worker(args) => vinebench::cmd::worker::run(&args),
    };
    // Exit codes: vinebench::cmd's module documentation (and docs/cli.md).
    match result {
        Ok(()) => std::process::ExitCode::SUCCESS,
        Err(e) => {
            let code = e
                .downcast_ref::<vinebench::cmd::Exit>()
                .map_or(1, |exit| exit.code);
            // Not eprintln!: a closed standard error must not turn the exit into a panic.
            let _ = writeln!(std::io::stderr(), "error: {e:#}");
            std::process::ExitCode::from(code)
        }
    }
}
