//! The watch on the data files (issue #31, SPEC §3: the memory copy is loaded from the file at
//! power-on *and after every saved edit*): TAB0.KOR, the constants file and the work offsets
//! file are polled; a
//! saved edit is loaded (`Controller::sync_files`), one that does not load raises an alarm
//! naming the file, line and code, and the memory copy stays.
//!
//! **Decided**: polling the content (SHA-256 of the bytes) rather than inotify. Editors save
//! by writing in place or by writing a new file and renaming it over the old one (vim, most
//! GUI editors), which replaces the inode an inotify watch holds; a content poll sees both
//! the same way, survives the file being deleted and created again, and costs one read of a
//! few kilobytes per period. A change is acted on once the content has stayed the same for
//! one period, so a half-written file is not reported as an error.

use std::path::PathBuf;
use std::sync::Arc;
use std::time::Duration;

use super::alarms::AlarmLog;
use crate::runtime::controller::Controller;
use crate::runtime::storage::{Fingerprint, StorageError, fingerprint};

/// How often the files are looked at.
pub const POLL_PERIOD: Duration = Duration::from_millis(250);

/// Alarm sources of the files (what `cncctl alarms` shows).
pub const OFFSETS_SOURCE: &str = "offsets_file";
pub const CONSTANTS_SOURCE: &str = "constants_file";
pub const WORK_OFFSETS_SOURCE: &str = "work_offsets_file";

/// The bytes' fingerprint, `None` for a missing or unreadable file.
fn look(path: &PathBuf) -> Option<Fingerprint> {
    std::fs::read(path).ok().map(|b| fingerprint(&b))
}

/// Starts the watch (needs a tokio runtime); it ends when the API state is gone.
pub fn spawn(ctl: Arc<Controller>, log: Arc<AlarmLog>) {
    let paths = [
        ctl.config().storage.offsets_path(),
        ctl.config().storage.constants_path(),
        ctl.config().storage.work_offsets_path(),
    ];
    tokio::spawn(async move {
        let mut previous = paths.clone().map(|p| look(&p));
        let mut acted = previous;
        let mut every = tokio::time::interval(POLL_PERIOD);
        every.set_missed_tick_behavior(tokio::time::MissedTickBehavior::Delay);
        loop {
            every.tick().await;
            if Arc::strong_count(&log) == 1 {
                return; // the API state is gone
            }
            let p = paths.clone();
            let Ok(now) = tokio::task::spawn_blocking(move || p.map(|p| look(&p))).await else {
                return;
            };
            // Stable for one period and not yet acted on.
            let settled = now == previous && now != acted;
            previous = now;
            if !settled {
                continue;
            }
            acted = now;
            let c = ctl.clone();
            let Ok(sync) = tokio::task::spawn_blocking(move || c.sync_files()).await else {
                return;
            };
            report(&log, OFFSETS_SOURCE, sync.offsets);
            report(&log, CONSTANTS_SOURCE, sync.constants);
            report(&log, WORK_OFFSETS_SOURCE, sync.work_offsets);
        }
    });
}

/// A file that loads clears its alarm; one that does not load raises it (once per saved
/// change: the watch calls this only when the content changed).
fn report(log: &AlarmLog, source: &str, outcome: Result<bool, StorageError>) {
    match outcome {
        Ok(loaded) => {
            if loaded {
                tracing::info!(source, "saved edit of the file loaded");
            }
            log.clear(source);
        }
        Err(e) => log.raise(source, format!("[{}] {e}", e.code())),
    }
}
