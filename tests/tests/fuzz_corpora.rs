//! The fuzz corpora and regressions (`fuzz/corpus/TARGET`, `fuzz/regressions/TARGET`) replayed
//! on stable through the fuzz targets' own checks (`umbra_tests::fuzz::run`): every kept input,
//! among them each crash the fuzzers found (minimised), must read or fail without a panic and
//! with the accepted-input properties holding. No fuzzing here; `fuzz/run.sh` fuzzes.

use std::path::PathBuf;
use umbra_tests::fuzz::{run, Target};

fn fuzz_dir() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .parent()
        .unwrap()
        .join("fuzz")
}

fn inputs(kind: &str, t: Target) -> Vec<PathBuf> {
    let dir = fuzz_dir().join(kind).join(t.name());
    let Ok(rd) = std::fs::read_dir(&dir) else {
        return vec![];
    };
    let mut v: Vec<PathBuf> = rd
        .flatten()
        .map(|e| e.path())
        .filter(|p| p.is_file())
        .collect();
    v.sort();
    v
}

#[test]
fn every_target_has_a_seed_corpus_and_a_dictionary() {
    for t in Target::ALL {
        assert!(
            !inputs("corpus", t).is_empty(),
            "fuzz/corpus/{} is empty",
            t.name()
        );
        let dict = fuzz_dir().join("dict").join(format!("{}.dict", t.name()));
        assert!(dict.is_file(), "{} missing", dict.display());
        let bin = fuzz_dir()
            .join("fuzz_targets")
            .join(format!("{}.rs", t.name()));
        assert!(bin.is_file(), "{} missing", bin.display());
    }
}

#[test]
fn corpora_and_regressions_replay_without_a_panic() {
    let mut n = 0;
    let mut failures = Vec::new();
    for t in Target::ALL {
        for p in inputs("corpus", t)
            .into_iter()
            .chain(inputs("regressions", t))
        {
            let bytes = std::fs::read(&p).unwrap();
            if std::panic::catch_unwind(|| run(t, &bytes)).is_err() {
                failures.push(p.display().to_string());
            }
            n += 1;
        }
    }
    assert!(
        failures.is_empty(),
        "{} of {n} inputs failed: {failures:?}",
        failures.len()
    );
    assert!(n >= 17, "{n} inputs");
}
