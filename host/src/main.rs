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
    /// Run the simulator along a scenario and optionally dump its sensor data.
    Simulate(vinebench::cmd::simulate::SimulateArgs),
    /// Evaluate an estimated trajectory against ground truth (APE / RPE, as evo does).
    Eval(vinebench::cmd::eval::EvalArgs),
}

fn main() -> std::process::ExitCode {
    let cli = Cli::parse();
    let result = match cli.command {
        Command::Simulate(args) => vinebench::cmd::simulate::run(&args),
        Command::Eval(args) => vinebench::cmd::eval::run(&args),
    };
    match result {
        Ok(()) => std::process::ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e:#}");
            std::process::ExitCode::FAILURE
        }
    }
}
