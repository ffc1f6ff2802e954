//! The daemon the fuzz entries of the API's doors call into (`fuzz/`, issue #50): one tokio
//! current-thread runtime and one API state over a controller on the built-in simulated
//! machine, built once per process (a controller per input would cap a target at a few runs
//! per second). Its storage is a directory of its own in memory where Linux has `/dev/shm`
//! (else under the system's temporary directory); a rig removes those of ended processes.

use std::sync::Arc;

use super::ApiState;
use crate::runtime::config::{Config, Role};
use crate::runtime::controller::{ClockKind, Controller};

pub(crate) struct Rig {
    pub rt: tokio::runtime::Runtime,
    pub st: Arc<ApiState>,
}

impl Rig {
    /// A rig whose storage directory is named after `target` and this process.
    pub(crate) fn start(target: &str) -> Rig {
        let rt = tokio::runtime::Builder::new_current_thread()
            .enable_all()
            .build()
            .expect("fuzz rig: tokio runtime");
        let mut cfg = Config::default();
        let scratch = scratch_dir();
        remove_dead_rigs(&scratch);
        cfg.storage.dir = scratch.join(format!("cncd-fuzz-{target}-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&cfg.storage.dir);
        // Locking memory needs a privilege the fuzz machine need not have.
        cfg.rt.lock_memory = false;
        // Every input must answer within the rig's seconds, and fast: two seconds of machining
        // exercise the velocity plot's door and its bound (a minute took half the runs' time).
        cfg.api.velocity_plot_max_h = 2.0 / 3600.0;
        // The grpc-web target relies on it: a request without a token must not move the
        // machine or write files.
        assert_eq!(cfg.api.loopback_role, Role::Observer);
        let st = rt.block_on(async {
            let ctl = Controller::start(cfg, ClockKind::Monotonic).expect("fuzz rig: controller");
            ApiState::new(ctl).expect("fuzz rig: API state")
        });
        Rig { rt, st }
    }
}

/// A library commit syncs the program and its directory to disk: in memory (tmpfs) that costs
/// nothing, on a disk it would cap the upload target at a few hundred runs per second.
fn scratch_dir() -> std::path::PathBuf {
    let shm = std::path::Path::new("/dev/shm");
    if shm.is_dir() {
        shm.to_owned()
    } else {
        std::env::temp_dir()
    }
}

/// Removes the storage of rigs whose process has ended (a rig lives as long as its process, so
/// it cannot remove its own).
fn remove_dead_rigs(scratch: &std::path::Path) {
    let Ok(dir) = std::fs::read_dir(scratch) else {
        return;
    };
    for e in dir.flatten() {
        let name = e.file_name();
        let Some(rest) = name.to_str().and_then(|n| n.strip_prefix("cncd-fuzz-")) else {
            continue;
        };
        let pid = rest.rsplit('-').next().and_then(|p| p.parse::<u32>().ok());
        if pid.is_some_and(|p| !std::path::Path::new(&format!("/proc/{p}")).exists()) {
            let _ = std::fs::remove_dir_all(e.path());
        }
    }
}

thread_local! {
    static INLINE_BLOCKING: std::cell::Cell<bool> = const { std::cell::Cell::new(false) };
}

/// In fuzz builds, a target whose calls never block on the runtime (the upload target: its
/// closures write files and validate) runs `api::blocking`'s work on its own thread: the
/// hand-over to tokio's blocking pool and back, two thread wake-ups a call, was most of its
/// time. The stable entry (`tests/tests/fuzz_entries.rs`) still runs the pool.
#[cfg(fuzzing)]
pub(crate) fn inline_blocking() -> bool {
    INLINE_BLOCKING.with(|c| c.get())
}

/// Whether work that would go to a thread of its own runs on the caller's instead (the
/// upload target in fuzz builds, see [`inline_blocking`]: an upload's validation and the
/// selection's outline, a thread and its wake-ups per input, took three quarters of a run).
pub(crate) fn inline_threads() -> bool {
    #[cfg(fuzzing)]
    return inline_blocking();
    #[cfg(not(fuzzing))]
    false
}

pub(crate) fn set_inline_blocking(on: bool) {
    INLINE_BLOCKING.with(|c| c.set(on));
}
