//! Where the daemon's `tracing` events go: the systemd journal when systemd connected our
//! stderr to it (`JOURNAL_STREAM`), plain stderr otherwise.
//!
//! In the journal every event field becomes a journal field with the prefix `CNC_`
//! (`CNC_BLOCK`, `CNC_LINE`, `CNC_AXIS`, `CNC_JOB`...), so motion events can be filtered:
//! `journalctl -u cncd CNC_AXIS=X`. The prefix keeps our fields apart from the journal's own
//! (`PRIORITY`, `MESSAGE`...).
//!
//! Also here: [`rt_health`], which turns the real-time statistics of the snapshots into journal
//! events (overruns as they happen, a summary now and then). Formatting happens on the Tokio
//! runtime, never on the real-time thread.

use std::fs::File;
use std::io::IsTerminal;
use std::os::unix::fs::MetadataExt;
use std::time::Duration;

use tokio::sync::watch;
use tracing_subscriber::EnvFilter;
use tracing_subscriber::layer::SubscriberExt;
use tracing_subscriber::util::SubscriberInitExt;

use super::rt::Snapshot;

/// A block number as a log field: `10` for `N10`, `-` for a block without number or no block.
/// Plain, so the journal can be filtered with `CNC_BLOCK=10` (`?Option` would log `Some(10)`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct BlockNo(pub Option<u32>);

impl std::fmt::Display for BlockNo {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self.0 {
            Some(n) => write!(f, "{n}"),
            None => f.write_str("-"),
        }
    }
}

/// Where logs go.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum LogTarget {
    /// The journal when stderr is connected to it (run by systemd), stderr otherwise.
    Auto,
    /// The systemd journal (native protocol, structured fields).
    Journal,
    /// Plain text on stderr.
    Stderr,
}

/// Prefix of our fields in the journal.
pub const JOURNAL_FIELD_PREFIX: &str = "CNC";

/// True when stderr is the journal stream systemd set up for this service: `JOURNAL_STREAM`
/// holds `device:inode` of that stream and it matches our stderr (`systemd.exec(5)`), so a child
/// whose stderr was redirected does not mistake an inherited variable for a journal.
pub fn stderr_is_journal() -> bool {
    let Some(v) = std::env::var_os("JOURNAL_STREAM") else {
        return false;
    };
    let Some((dev, ino)) = v.to_str().and_then(|s| s.split_once(':')) else {
        return false;
    };
    let (Ok(dev), Ok(ino)) = (dev.parse::<u64>(), ino.parse::<u64>()) else {
        return false;
    };
    let Ok(fd) = std::os::fd::AsFd::as_fd(&std::io::stderr()).try_clone_to_owned() else {
        return false;
    };
    match File::from(fd).metadata() {
        Ok(m) => m.dev() == dev && m.ino() == ino,
        Err(_) => false,
    }
}

/// Installs the global subscriber. `RUST_LOG` filters (default `info`). Returns where the logs
/// go; when the journal was asked for but cannot be reached, logs go to stderr and a warning
/// says why.
pub fn init(target: LogTarget) -> LogTarget {
    let filter = || EnvFilter::try_from_default_env().unwrap_or_else(|_| EnvFilter::new("info"));
    let want_journal = match target {
        LogTarget::Journal => true,
        LogTarget::Stderr => false,
        LogTarget::Auto => stderr_is_journal(),
    };
    let mut journal_error = None;
    if want_journal {
        match tracing_journald::layer() {
            Ok(layer) => {
                let layer = layer
                    .with_field_prefix(Some(JOURNAL_FIELD_PREFIX.into()))
                    .with_syslog_identifier("cncd".into());
                tracing_subscriber::registry()
                    .with(filter())
                    .with(layer)
                    .init();
                return LogTarget::Journal;
            }
            Err(e) => journal_error = Some(e),
        }
    }
    tracing_subscriber::registry()
        .with(filter())
        .with(
            tracing_subscriber::fmt::layer()
                .with_writer(std::io::stderr)
                .with_ansi(std::io::stderr().is_terminal()),
        )
        .init();
    if let Some(e) = journal_error {
        tracing::warn!("cannot log to the journal ({e}): logging to stderr");
    }
    LogTarget::Stderr
}

/// Logs the real-time statistics from the snapshots: a warning (with job, block and line) each
/// time the overrun count grew since the previous look, every `every`; and an info summary
/// every `summary_every`. Runs until the controller goes away or the task is aborted.
pub async fn rt_health(
    status: watch::Receiver<Snapshot>,
    every: Duration,
    summary_every: Duration,
) {
    let mut ticker = tokio::time::interval(every);
    ticker.set_missed_tick_behavior(tokio::time::MissedTickBehavior::Delay);
    ticker.tick().await;
    let mut last = status.borrow().tick.stats;
    let mut since_summary = Duration::ZERO;
    loop {
        ticker.tick().await;
        if status.has_changed().is_err() {
            return;
        }
        let s = *status.borrow();
        let t = s.tick.stats;
        if t.overruns > last.overruns {
            tracing::warn!(
                overruns = t.overruns - last.overruns,
                total = t.overruns,
                lateness_max_us = t.lateness_max_us,
                state = ?s.state,
                job = s.progress.job,
                block = %BlockNo(s.progress.block_n),
                line = s.progress.line,
                "real-time deadlines missed"
            );
        }
        since_summary += every;
        if since_summary >= summary_every {
            since_summary = Duration::ZERO;
            tracing::info!(
                cycle_us = s.tick.cycle_ns / 1000,
                ticks = t.ticks,
                overruns = t.overruns,
                lateness_p50_us = t.lateness_p50_us,
                lateness_p99_us = t.lateness_p99_us,
                lateness_max_us = t.lateness_max_us,
                "real-time tick statistics"
            );
        }
        last = t;
    }
}
