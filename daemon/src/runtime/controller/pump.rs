//! The status thread: the RT thread's snapshots into the watch channel every reader uses,
//! `G92` writes applied when their block executes, state changes and alarms logged.

use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::{Arc, Mutex};
use std::time::Duration;

use tokio::sync::watch;

use crate::runtime::logging::BlockNo;
use crate::runtime::pipeline::Execution;
use crate::runtime::rt::Snapshot;
use crate::runtime::storage::OffsetStore;

/// The status thread: copies RT snapshots into the watch channel, follows execution (`G92`
/// writes apply when their block executes, SPEC §3 c) and logs state changes and alarms
/// (formatting happens here, never on the RT thread).
pub(crate) struct Pump {
    pub(crate) execution: Arc<Mutex<Execution>>,
    pub(crate) offsets: Arc<Mutex<OffsetStore>>,
    pub(crate) generation: Arc<AtomicU64>,
    pub(crate) axis_names: Vec<char>,
}

impl Pump {
    pub(super) fn run(
        &self,
        out: &mut triple_buffer::Output<Snapshot>,
        tx: &watch::Sender<Snapshot>,
        stop: &AtomicBool,
    ) {
        let mut last = *out.read();
        while !stop.load(Ordering::Relaxed) {
            std::thread::sleep(Duration::from_millis(1));
            if !out.update() {
                continue;
            }
            let s = *out.output_buffer();
            self.log_changes(&last, &s);
            // Before the snapshot is published: who sees the job ended sees its writes.
            self.apply_executed_writes(&s);
            last = s;
            tx.send_replace(s);
        }
    }

    pub(crate) fn apply_executed_writes(&self, s: &Snapshot) {
        let mut applied = false;
        // Lock order: execution, then offsets (nothing takes them the other way round).
        let mut execution = self.execution.lock().unwrap_or_else(|e| e.into_inner());
        execution.observe(s, |w| {
            let mut offsets = self.offsets.lock().unwrap_or_else(|e| e.into_inner());
            // Validated by the interpreter with the same table; a refusal here means the
            // table changed under the program (operator edit): say so, keep running.
            if let Err(m) = offsets.program_write(&w.edit) {
                tracing::error!(block = %BlockNo(w.n), line = w.line, "G92 write not applied: {m}");
            }
            applied = true;
        });
        if applied {
            self.generation.fetch_add(1, Ordering::AcqRel);
        }
    }

    fn log_changes(&self, last: &Snapshot, s: &Snapshot) {
        if s.alarm.fault != last.alarm.fault
            && let Some(f) = s.alarm.fault
        {
            let axis =
                hal::fault_axis_label(f.axis, &self.axis_names).unwrap_or_else(|| "-".into());
            tracing::error!(axis, node = ?f.node, block = %BlockNo(s.progress.block_n), line = s.progress.line, "alarm: {}", f.reason);
        }
        if s.state != last.state {
            tracing::info!(state = ?s.state, job = s.progress.job, block = %BlockNo(s.progress.block_n), line = s.progress.line, "machine state");
        }
    }
}
