//! Replays the committed seed corpus (`fuzz/corpus/<target>/`) and every regression input
//! (`fuzz/regressions/<target>/`, the inputs that once crashed a parser) through the fuzz
//! targets' bodies, on the stable toolchain: a parser that panics on any of them fails this
//! test. Fuzzing itself runs outside CI (`docs/fuzzing.md`).

use std::path::{Path, PathBuf};

use fuzz_targets::{TARGETS, Target};

fn fuzz_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("..")
}

/// The files of `dir`, sorted; none if it does not exist.
fn inputs(dir: &Path) -> Vec<PathBuf> {
    let Ok(entries) = std::fs::read_dir(dir) else {
        return Vec::new();
    };
    let mut files: Vec<PathBuf> = entries
        .map(|e| e.expect("a directory entry").path())
        .filter(|p| p.is_file())
        .collect();
    files.sort();
    files
}

/// Runs `target` on every input, naming the input of a panic.
fn replay(name: &str, target: Target, files: &[PathBuf]) {
    for file in files {
        let data = std::fs::read(file).unwrap_or_else(|e| panic!("{}: {e}", file.display()));
        let result = std::panic::catch_unwind(|| target(&data));
        assert!(
            result.is_ok(),
            "target {name} panicked on {} (see above)",
            file.display()
        );
    }
}

#[test]
fn every_target_has_a_seed_corpus_and_survives_it() {
    let corpus = fuzz_dir().join("corpus");
    let mut total = 0;
    for &(name, target) in TARGETS {
        let files = inputs(&corpus.join(name));
        assert!(
            !files.is_empty(),
            "fuzz/corpus/{name}/ is missing or empty: every target keeps a seed corpus"
        );
        replay(name, target, &files);
        total += files.len();
    }
    // Every corpus folder is a target's: a renamed target leaves no corpus unreplayed.
    for entry in std::fs::read_dir(&corpus).expect("fuzz/corpus") {
        let name = entry.expect("an entry").file_name();
        let name = name.to_string_lossy();
        assert!(
            TARGETS.iter().any(|(t, _)| *t == name),
            "fuzz/corpus/{name}/ belongs to no target"
        );
    }
    eprintln!(
        "{total} corpus inputs replayed over {} targets",
        TARGETS.len()
    );
}

#[test]
fn every_regression_input_is_answered_without_a_panic() {
    let regressions = fuzz_dir().join("regressions");
    assert!(
        regressions.is_dir(),
        "fuzz/regressions/ is missing: it holds the inputs of every crash found"
    );
    let mut total = 0;
    for entry in std::fs::read_dir(&regressions).expect("fuzz/regressions") {
        let dir = entry.expect("an entry").path();
        if !dir.is_dir() {
            continue;
        }
        let name = dir
            .file_name()
            .expect("a name")
            .to_string_lossy()
            .into_owned();
        let target = TARGETS
            .iter()
            .find(|(t, _)| *t == name)
            .unwrap_or_else(|| panic!("fuzz/regressions/{name}/ belongs to no target"))
            .1;
        let files = inputs(&dir);
        replay(&name, target, &files);
        total += files.len();
    }
    eprintln!("{total} regression inputs replayed");
}
