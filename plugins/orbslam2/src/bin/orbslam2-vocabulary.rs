//! Trains the ORB-SLAM2-style plugin's DBoW2 vocabulary on camera frames dumped by
//! `vinebench simulate --sensors rgbd --out DIR` (TUM RGB-D layout: `rgbd/rgb.txt` lists the
//! colour PNGs). ORB features are extracted exactly as the plugin does; the vocabulary is a
//! hierarchical k-means++ tree (`slam_common::place::vocabulary`). `scripts/train-vocabulary.sh`
//! runs the whole recipe on a world different from the benchmark's.
//!
//! Usage: `orbslam2-vocabulary --out FILE [--k 10] [--levels 6] [--seed 0] [--every 10] DIR...`
//!
//! `orbslam2-vocabulary --export-dbow2-text VOCABULARY.dbow OUT.txt` writes a trained
//! vocabulary in DBoW2's text format, the `ORBvoc.txt` format the real ORB-SLAM2/3 load
//! (`Vocabulary::write_dbow2_text`); `scripts/setup.sh` makes the `orbslam3` adapter's
//! vocabulary this way.

use std::path::{Path, PathBuf};
use std::process::ExitCode;

use orbslam2::orb::{OrbConfig, OrbExtractor};
use plugin_api::gray_from_rgb;
use slam_common::place::vocabulary::{Descriptor, TrainConfig, Vocabulary};

struct Args {
    out: PathBuf,
    train: TrainConfig,
    every: usize,
    dirs: Vec<PathBuf>,
}

fn parse() -> Result<Args, String> {
    let mut args = Args {
        out: PathBuf::new(),
        train: TrainConfig::default(),
        every: 10,
        dirs: Vec::new(),
    };
    let mut it = std::env::args().skip(1);
    while let Some(a) = it.next() {
        let mut value = |name: &str| it.next().ok_or_else(|| format!("{name} needs a value"));
        let number = |name: &str, v: String| {
            v.parse::<usize>()
                .map_err(|_| format!("{name}: not a number: {v}"))
        };
        match a.as_str() {
            "--out" => args.out = PathBuf::from(value("--out")?),
            "--k" => args.train.k = number("--k", value("--k")?)?,
            "--levels" => args.train.levels = number("--levels", value("--levels")?)?,
            "--seed" => args.train.seed = number("--seed", value("--seed")?)? as u64,
            "--every" => args.every = number("--every", value("--every")?)?.max(1),
            "-h" | "--help" => {
                return Err("usage: orbslam2-vocabulary --out FILE [--k 10] [--levels 6] [--seed 0] [--every 10] DIR...".into());
            }
            other if other.starts_with("--") => return Err(format!("unknown option {other}")),
            dir => args.dirs.push(PathBuf::from(dir)),
        }
    }
    if args.out.as_os_str().is_empty() || args.dirs.is_empty() {
        return Err("usage: orbslam2-vocabulary --out FILE [--k 10] [--levels 6] [--seed 0] [--every 10] DIR...".into());
    }
    Ok(args)
}

fn read_rgb(path: &Path) -> Result<(Vec<u8>, usize, usize), String> {
    let file = std::fs::File::open(path).map_err(|e| format!("{}: {e}", path.display()))?;
    let mut reader = png::Decoder::new(std::io::BufReader::new(file))
        .read_info()
        .map_err(|e| format!("{}: {e}", path.display()))?;
    let mut buf = vec![
        0;
        reader
            .output_buffer_size()
            .ok_or_else(|| format!("{}: too large", path.display()))?
    ];
    let info = reader
        .next_frame(&mut buf)
        .map_err(|e| format!("{}: {e}", path.display()))?;
    if info.color_type != png::ColorType::Rgb || info.bit_depth != png::BitDepth::Eight {
        return Err(format!("{}: not an 8-bit RGB image", path.display()));
    }
    buf.truncate(info.buffer_size());
    Ok((buf, info.width as usize, info.height as usize))
}

/// `--export-dbow2-text IN OUT`.
fn export(input: &Path, output: &Path) -> Result<(), String> {
    let vocabulary = Vocabulary::load(input).map_err(|e| format!("{}: {e}", input.display()))?;
    let tmp = output.with_extension("txt.partial");
    let mut file = std::fs::File::create(&tmp).map_err(|e| format!("{}: {e}", tmp.display()))?;
    vocabulary
        .write_dbow2_text(&mut file)
        .map_err(|e| format!("{}: {e}", tmp.display()))?;
    std::fs::rename(&tmp, output).map_err(|e| format!("{}: {e}", output.display()))?;
    println!(
        "{}: {} nodes, {} words -> {}",
        input.display(),
        vocabulary.node_count(),
        vocabulary.word_count(),
        output.display()
    );
    Ok(())
}

fn run() -> Result<(), String> {
    let argv: Vec<String> = std::env::args().skip(1).collect();
    if argv.first().map(String::as_str) == Some("--export-dbow2-text") {
        let [_, input, output] = argv.as_slice() else {
            return Err(
                "usage: orbslam2-vocabulary --export-dbow2-text VOCABULARY.dbow OUT.txt".into(),
            );
        };
        return export(Path::new(input), Path::new(output));
    }
    let args = parse()?;
    let mut extractor =
        OrbExtractor::new(OrbConfig::default()).map_err(|e| format!("ORB extractor: {e}"))?;
    let mut images: Vec<Vec<Descriptor>> = Vec::new();
    for dir in &args.dirs {
        let list = dir.join("rgbd/rgb.txt");
        let text =
            std::fs::read_to_string(&list).map_err(|e| format!("{}: {e}", list.display()))?;
        let files: Vec<&str> = text
            .lines()
            .filter(|l| !l.starts_with('#') && !l.trim().is_empty())
            .filter_map(|l| l.split_whitespace().nth(1))
            .collect();
        for file in files.iter().step_by(args.every) {
            let (rgb, w, h) = read_rgb(&dir.join("rgbd").join(file))?;
            let gray = gray_from_rgb(&rgb, w, h);
            let (_, descriptors) = extractor
                .extract(&gray, w, h)
                .map_err(|e| format!("{file}: ORB: {e}"))?;
            images.push(descriptors);
        }
        eprintln!("{}: {} frames so far", dir.display(), images.len());
    }
    let descriptors: usize = images.iter().map(Vec::len).sum();
    let start = std::time::Instant::now();
    let vocabulary =
        Vocabulary::train(&images, &args.train).map_err(|e| format!("training: {e}"))?;
    vocabulary
        .save(&args.out)
        .map_err(|e| format!("{}: {e}", args.out.display()))?;
    println!(
        "{} images, {descriptors} descriptors -> {} words (k {}, L {}, seed {}) in {:.1} s: {}",
        images.len(),
        vocabulary.word_count(),
        args.train.k,
        args.train.levels,
        args.train.seed,
        start.elapsed().as_secs_f64(),
        args.out.display()
    );
    Ok(())
}

fn main() -> ExitCode {
    match run() {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("orbslam2-vocabulary: {e}");
            ExitCode::FAILURE
        }
    }
}
