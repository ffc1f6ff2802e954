//! A writer process is SIGKILLed at random moments while it rewrites TAB0.KOR in a loop; after
//! every kill the file must parse and be exactly the old or the new table (SPEC §3, issue #3).
//!
//! The writer is this same test binary, re-executed with an environment variable that turns
//! the helper `writer_child` into an endless writer.

use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use daemon::runtime::storage::{temp_path, write_atomic};
use kernel::offsets::{self, KorFile, OffsetEntry, OffsetTable};

const CHILD_ENV: &str = "CNCD_STORAGE_KILL_CHILD_DIR";
const AXES: [char; 3] = ['X', 'Y', 'Z'];
const ROUNDS: usize = 300;

/// Two full tables that differ in every entry, so a torn file cannot equal either.
fn tables() -> (KorFile, KorFile) {
    let make = |k: f64| {
        let mut t = OffsetTable::new();
        for n in 1..=99u8 {
            let v = f64::from(n) + k;
            t.set_entry(
                n,
                OffsetEntry {
                    radius_mm: v / 8.0,
                    length_mm: [v, -v, v * 2.0, k],
                },
            )
            .unwrap();
        }
        KorFile {
            comment: format!("table {k}\n"),
            table: t,
        }
    };
    (make(0.5), make(1000.25))
}

/// Helper, not a test: does nothing unless started by `sigkill_*` below, then rewrites the
/// file forever (until killed).
#[test]
fn writer_child() {
    let Ok(dir) = std::env::var(CHILD_ENV) else {
        return;
    };
    let dir = PathBuf::from(dir);
    let (a, b) = tables();
    let texts = [offsets::write(&a, &AXES), offsets::write(&b, &AXES)];
    let path = dir.join("TAB0.KOR");
    for k in 0usize.. {
        write_atomic(&path, texts[k % 2].as_bytes()).unwrap();
        if k == 1 {
            std::fs::write(dir.join("ready"), b"1").unwrap();
        }
    }
}

/// Small deterministic generator for the kill delays (seeded, so a failure can be replayed).
struct XorShift(u64);
impl XorShift {
    fn next(&mut self) -> u64 {
        self.0 ^= self.0 << 13;
        self.0 ^= self.0 >> 7;
        self.0 ^= self.0 << 17;
        self.0
    }
}

fn wait_for(path: &Path) {
    let t = Instant::now();
    while !path.exists() {
        assert!(
            t.elapsed() < Duration::from_secs(30),
            "writer did not start"
        );
        std::thread::sleep(Duration::from_micros(200));
    }
}

#[test]
fn sigkill_during_writes_leaves_old_or_new_table() {
    let dir = PathBuf::from(env!("CARGO_TARGET_TMPDIR"))
        .join(format!("storage_kill_{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("TAB0.KOR");
    let (a, b) = tables();
    write_atomic(&path, offsets::write(&a, &AXES).as_bytes()).unwrap();

    let exe = std::env::current_exe().unwrap();
    let mut rng = XorShift(0x9E37_79B9_7F4A_7C15);
    let (mut seen_a, mut seen_b, mut temp_left) = (0, 0, 0);
    for round in 0..ROUNDS {
        let _ = std::fs::remove_file(dir.join("ready"));
        let mut child = Command::new(&exe)
            .args(["writer_child", "--exact", "--test-threads=1", "--nocapture"])
            .env(CHILD_ENV, &dir)
            .stdout(Stdio::null())
            .stderr(Stdio::null())
            .spawn()
            .unwrap();
        wait_for(&dir.join("ready"));
        std::thread::sleep(Duration::from_micros(rng.next() % 4000));
        child.kill().unwrap(); // SIGKILL on Unix
        child.wait().unwrap();

        let text = std::fs::read_to_string(&path)
            .unwrap_or_else(|e| panic!("round {round}: file unreadable after SIGKILL: {e}"));
        let got = offsets::parse(&text, &AXES)
            .unwrap_or_else(|e| panic!("round {round}: file does not parse after SIGKILL: {e:?}"));
        if got == a {
            seen_a += 1;
        } else if got == b {
            seen_b += 1;
        } else {
            panic!("round {round}: the file is neither the old nor the new table");
        }
        if temp_path(&path).exists() {
            temp_left += 1; // killed between creating the temp file and the rename
        }
    }
    eprintln!(
        "{ROUNDS} SIGKILLs: old/new table A {seen_a} times, B {seen_b} times; \
         killed mid-write (temp file left) {temp_left} times"
    );
    // Kills landed at different points of the loop, not always at the same place.
    assert!(seen_a > 0 && seen_b > 0, "A {seen_a}, B {seen_b}");
    std::fs::remove_dir_all(&dir).unwrap();
}
