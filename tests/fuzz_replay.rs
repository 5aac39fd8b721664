//! Replays the fuzz corpus (`tests/fuzz/corpus/<target>/`) and every input a
//! campaign found a crash with (`tests/fuzz/regressions/<target>/`) through
//! the targets' bodies, on stable, in seconds. Campaigns themselves run on
//! nightly: scripts/fuzz-campaign.sh.
use std::path::{Path, PathBuf};
use system_tests::fuzz_bodies::TARGETS;

fn inputs(kind: &str, target: &str) -> Vec<PathBuf> {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("fuzz").join(kind).join(target);
    let Ok(entries) = std::fs::read_dir(&dir) else { return Vec::new() };
    let mut files: Vec<PathBuf> = entries.map(|e| e.unwrap().path()).filter(|p| p.is_file()).collect();
    files.sort();
    files
}

fn replay(kind: &str) -> usize {
    let mut total = 0;
    for (name, body) in TARGETS {
        for path in inputs(kind, name) {
            let data = std::fs::read(&path).unwrap();
            let r = std::panic::catch_unwind(|| body(&data));
            assert!(r.is_ok(), "{name}: {} fails", path.display());
            total += 1;
        }
    }
    total
}

#[test]
fn corpus_replays_cleanly() {
    // Every target has a corpus checked in.
    for (name, _) in TARGETS {
        assert!(!inputs("corpus", name).is_empty(), "no corpus for {name}");
    }
    assert!(replay("corpus") >= TARGETS.len());
}

#[test]
fn regression_inputs_replay_cleanly() {
    replay("regressions");
}
