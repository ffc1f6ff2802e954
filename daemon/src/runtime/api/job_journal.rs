//! Interrupted jobs (issue #31): while a program runs, the data directory holds `job.running`
//! (program, job, the block and line reached, when it started); it is removed when the job
//! ends. Found at start-up, it means cncd ended during the job (killed, power cut, crash): an
//! `interrupted_job` alarm names the program and the block, in the alarm history with its
//! time, until the next job starts.
//!
//! The record is written when a job starts and then at most once a second while its block
//! changes (a small atomic write on the API side; the RT thread never waits for it), so the
//! block named is the one reached at most about a second before the end.

use std::path::{Path, PathBuf};
use std::sync::Weak;
use std::time::{Duration, Instant, SystemTime, UNIX_EPOCH};

use proto::v1 as pb;
use serde_json::{Value, json};

use super::ApiState;
use crate::runtime::rt::MachineState;
use crate::runtime::storage::write_atomic;

/// The record's file in the data directory.
pub const JOURNAL_FILE: &str = "job.running";
/// Alarm source of an interrupted job.
pub const SOURCE: &str = "interrupted_job";

const POLL: Duration = Duration::from_millis(100);
const REWRITE_AT_MOST_EVERY: Duration = Duration::from_secs(1);

fn now_ms() -> u64 {
    SystemTime::now()
        .duration_since(UNIX_EPOCH)
        .map_or(0, |d| d.as_millis() as u64)
}

/// What the record holds.
#[derive(Clone, Debug, PartialEq)]
struct Record {
    program: String,
    job: u32,
    block: Option<u32>,
    line: u32,
    started_unix_ms: u64,
}

impl Record {
    fn of(s: &pb::Status, started_unix_ms: u64) -> Record {
        Record {
            program: s.program.clone(),
            job: s.job,
            block: s.block,
            line: s.line,
            started_unix_ms,
        }
    }

    fn json(&self) -> Value {
        json!({"program": self.program, "job": self.job, "block": self.block, "line": self.line,
            "started_unix_ms": self.started_unix_ms, "written_unix_ms": now_ms()})
    }

    fn read(path: &Path) -> Option<Record> {
        let v: Value = serde_json::from_str(&std::fs::read_to_string(path).ok()?).ok()?;
        Some(Record {
            program: v["program"].as_str().unwrap_or("").into(),
            job: v["job"].as_u64().unwrap_or(0) as u32,
            block: v["block"].as_u64().map(|b| b as u32),
            line: v["line"].as_u64().unwrap_or(0) as u32,
            started_unix_ms: v["started_unix_ms"].as_u64().unwrap_or(0),
        })
    }

    /// The alarm text: program, job, block and line, when it started.
    fn alarm(&self) -> String {
        let block = self.block.map_or_else(|| "-".into(), |n| format!("N{n}"));
        let started = jiff::Timestamp::from_millisecond(self.started_unix_ms as i64)
            .map(|t| t.to_string())
            .unwrap_or_default();
        format!(
            "cncd ended during program {:?} (job {}, started {started}): last at block {block}, \
             line {}; check the part and the tool, then run it again",
            self.program, self.job, self.line
        )
    }
}

/// Reports a record left by the last run, then keeps the record of this run's jobs.
pub fn spawn(state: Weak<ApiState>) {
    let Some(st) = state.upgrade() else { return };
    let path: PathBuf = st.ctl.config().storage.dir.join(JOURNAL_FILE);
    if let Some(r) = Record::read(&path) {
        tracing::warn!(program = %r.program, job = r.job, line = r.line, "a job was interrupted");
        st.alarms.raise(SOURCE, r.alarm());
        let _ = std::fs::remove_file(&path);
    }
    drop(st);
    tokio::spawn(async move {
        let mut written: Option<(Record, Instant)> = None;
        let mut every = tokio::time::interval(POLL);
        every.set_missed_tick_behavior(tokio::time::MissedTickBehavior::Delay);
        loop {
            every.tick().await;
            let Some(st) = state.upgrade() else { return };
            let s = st.ctl.snapshot();
            let running = matches!(
                s.state,
                MachineState::Running | MachineState::Hold | MachineState::Stopping
            );
            if !running || s.progress.job == 0 {
                if written.take().is_some() {
                    let p = path.clone();
                    let _ = tokio::task::spawn_blocking(move || std::fs::remove_file(p)).await;
                }
                continue;
            }
            let status = st.status(&s);
            let new_job = written
                .as_ref()
                .is_none_or(|(r, _)| r.job != s.progress.job);
            let started = match &written {
                Some((r, _)) if !new_job => r.started_unix_ms,
                _ => now_ms(),
            };
            let rec = Record::of(&status, started);
            let due = written
                .as_ref()
                .is_none_or(|(r, at)| *r != rec && at.elapsed() >= REWRITE_AT_MOST_EVERY);
            if new_job {
                st.alarms.clear(SOURCE);
            }
            if new_job || due {
                let (p, text) = (path.clone(), rec.json().to_string());
                let r =
                    tokio::task::spawn_blocking(move || write_atomic(&p, text.as_bytes())).await;
                if let Ok(Err(e)) = r {
                    tracing::warn!("cannot record the running job in {}: {e}", path.display());
                }
                written = Some((rec, Instant::now()));
            }
        }
    });
}
