//! The fuzz entries of the daemon's doors (fuzz/, issue #50) on stable, as `cargo test` runs
//! them: each target's committed seeds, then mutations of them (bytes flipped, cut, doubled),
//! must pass their entry's checks. cargo-fuzz runs the same entries for millions of inputs
//! (`scripts/fuzz.sh`).

use std::path::PathBuf;

fn seeds(target: &str) -> Vec<Vec<u8>> {
    let dir = PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("../fuzz/seeds")
        .join(target);
    let mut out: Vec<Vec<u8>> = std::fs::read_dir(&dir)
        .unwrap_or_else(|e| panic!("{}: {e}", dir.display()))
        .map(|e| std::fs::read(e.unwrap().path()).unwrap())
        .collect();
    assert!(!out.is_empty(), "no seeds for {target}");
    out.sort();
    out
}

/// Seeds and `n` deterministic mutations of them.
fn inputs(target: &str, n: usize) -> Vec<Vec<u8>> {
    let base = seeds(target);
    let mut x: u64 = 0x9E37_79B9_7F4A_7C15;
    let mut next = move || {
        x ^= x << 13;
        x ^= x >> 7;
        x ^= x << 17;
        x
    };
    let mut out = base.clone();
    for _ in 0..n {
        let mut v = base[next() as usize % base.len()].clone();
        for _ in 0..1 + next() % 4 {
            let len = v.len().max(1);
            match next() % 4 {
                0 if !v.is_empty() => v[next() as usize % len] = next() as u8,
                1 => v.truncate(next() as usize % len),
                2 => {
                    let at = next() as usize % (v.len() + 1);
                    v.insert(at, next() as u8);
                }
                _ => v.extend_from_within(..v.len() / 2),
            }
        }
        out.push(v);
    }
    out
}

#[test]
fn mtconnect_requests() {
    for d in inputs("mtconnect", 20_000) {
        daemon::mtconnect::fuzz::fuzz_entry(&d);
    }
}

#[test]
fn configuration_files() {
    for d in inputs("config", 3_000) {
        daemon::runtime::config::Config::fuzz_entry(&d);
    }
}

#[test]
fn code_pages() {
    for d in inputs("code_pages", 20_000) {
        kernel::program::encoding::fuzz_entry(&d);
    }
}

#[test]
fn grpc_web_requests() {
    for d in inputs("grpc_web", 20_000) {
        daemon::runtime::hmi::fuzz::fuzz_entry(&d);
    }
}

#[test]
fn upload_sessions() {
    for d in inputs("upload", 10_000) {
        daemon::runtime::api::upload_fuzz::fuzz_entry(&d);
    }
}
