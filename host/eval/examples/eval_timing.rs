//! Times the library on a TUM pair, stage by stage and end to end (read both files,
//! associate, SE(3)-align, APE translation, statistics), best of several runs.
//!
//! `cargo run --release -p vinebench-eval --example eval_timing -- GT.tum EST.tum [RUNS]`
//! (make a 100k-pose pair with `tests/evo/gen_pair.py 100000 DIR`).

use std::time::{Duration, Instant};

use eval::{
    Alignment, ApeOptions, Association, Statistics, align, ape_errors, associate, read_tum,
};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().collect();
    let [_, gt, est, rest @ ..] = args.as_slice() else {
        return Err("usage: eval_timing GT.tum EST.tum [RUNS]".into());
    };
    let runs: usize = rest.first().map_or(Ok(5), |r| r.parse())?;
    let mut best = [Duration::MAX; 5];
    let mut stats = None;
    for _ in 0..runs {
        let t0 = Instant::now();
        let reference = read_tum(gt)?;
        let estimate = read_tum(est)?;
        let t1 = Instant::now();
        let mut pairs = associate(&reference, &estimate, &Association::default())?;
        let t2 = Instant::now();
        align(&mut pairs, Alignment::Se3, None)?;
        let t3 = Instant::now();
        let errors = ape_errors(
            &pairs.reference,
            &pairs.estimate,
            ApeOptions::default().relation,
        );
        stats = Some(Statistics::from_errors(&errors)?);
        let t4 = Instant::now();
        for (slot, d) in best
            .iter_mut()
            .zip([t1 - t0, t2 - t1, t3 - t2, t4 - t3, t4 - t0])
        {
            *slot = (*slot).min(d);
        }
    }
    let stats = stats.ok_or("RUNS must be at least 1")?;
    println!(
        "pairs {} rmse {} (best of {runs} runs)",
        stats.pairs, stats.rmse
    );
    for (name, d) in [
        "read both files",
        "associate",
        "align se3",
        "ape + stats",
        "total",
    ]
    .iter()
    .zip(best)
    {
        println!("{name:>16}: {:8.3} ms", d.as_secs_f64() * 1e3);
    }
    Ok(())
}
