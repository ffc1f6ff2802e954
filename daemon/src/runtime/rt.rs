//! The real-time thread: a thin loop around [`RtCore`] on an absolute deadline grid of the bus
//! period (`[bus] cycle_ms`, 1..10 ms; the interpolator inside keeps 4 ms).
//!
//! Each turn: sleep until the core's next deadline, read the clock, run one tick of the core
//! (commands, segments, interpolation, KŘR, PLC, bus exchange, state machine, tick statistics),
//! publish its snapshot. The tick itself is in [`super::rt_core`], a pure state machine that the
//! tests also drive single-threaded with a simulated clock. After start-up this thread never
//! allocates, never takes a lock shared with non-RT code and never formats a log line: it talks
//! to the rest of the daemon only through two bounded lock-free SPSC rings (in) and a triple
//! buffer (out).

use std::sync::Arc;
use std::sync::atomic::AtomicU32;

use hal::DriveBus;
use kernel::plan::Segment;

use super::clock::Clock;
pub use super::rt_core::{
    JobMachine, MachineState, RtCommand, RtCore, RtCoreConfig, RtRings, Snapshot,
};

/// Everything the RT thread owns.
pub struct RtParts {
    pub bus: Box<dyn DriveBus>,
    pub clock: Box<dyn Clock>,
    pub commands: rtrb::Consumer<RtCommand>,
    pub segments: rtrb::Consumer<Segment>,
    pub status: triple_buffer::Input<Snapshot>,
    /// Id of the last job whose planning is complete (all its segments are on the ring).
    pub planned_job: Arc<AtomicU32>,
    /// What the core is built from.
    pub core: RtCoreConfig,
}

/// Runs the loop until a `Shutdown` command has brought the axes to rest.
pub fn run(parts: RtParts) {
    let RtParts {
        mut bus,
        mut clock,
        commands,
        segments,
        mut status,
        planned_job,
        core,
    } = parts;
    let mut rings = RtRings {
        commands,
        segments,
        planned_job,
    };
    let mut core = RtCore::new(core, bus.as_mut(), clock.now_ns());
    while !core.finished() {
        clock.sleep_until_ns(core.next_deadline_ns());
        let now = clock.now_ns();
        status.write(*core.tick(now, &mut rings, bus.as_mut()));
    }
    // The axes are at rest: the drives are switched off in order before the thread ends.
    core.shut_down_bus(bus.as_mut(), |t| clock.sleep_until_ns(t));
}

/// Asks for `SCHED_FIFO` at `priority` for the calling thread.
pub fn set_realtime_priority(priority: i32) -> std::io::Result<()> {
    let param = libc::sched_param {
        sched_priority: priority,
    };
    // SAFETY: plain syscall on the calling thread with a valid parameter struct.
    let rc = unsafe { libc::sched_setscheduler(0, libc::SCHED_FIFO, &param) };
    if rc == 0 {
        Ok(())
    } else {
        Err(std::io::Error::last_os_error())
    }
}

/// Locks current and future memory so the RT thread never takes a page fault.
pub fn lock_memory() -> std::io::Result<()> {
    // SAFETY: plain syscall.
    let rc = unsafe { libc::mlockall(libc::MCL_CURRENT | libc::MCL_FUTURE) };
    if rc == 0 {
        Ok(())
    } else {
        Err(std::io::Error::last_os_error())
    }
}
