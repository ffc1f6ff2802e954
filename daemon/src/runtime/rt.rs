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
    JobMachine, MachineState, ProbeOutcome, ProbeRequest, RtCommand, RtCore, RtCoreConfig, RtRings,
    Snapshot,
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

/// Stack size of the threads cncd starts: the real-time thread, the status pump, a job's
/// planner, and the async runtime's workers and blocking threads (where validation passes
/// run). Locked memory (`rt.lock_memory`, [`lock_memory`]) makes every page of every stack
/// resident, so Rust's 2 MiB default would cost 2 MiB a thread. Measured in an optimised
/// build: below 100 KiB for a million-block validation, a run and MDI, and the deepest
/// expression the ISO parser accepts (250 terms) takes below 128 KiB more. An unoptimised
/// build's frames are several times larger (that expression alone takes 512 KiB to 1 MiB
/// there), so debug builds keep the default.
pub const THREAD_STACK_BYTES: usize = if cfg!(debug_assertions) {
    2 << 20
} else {
    512 << 10
};

/// Sets glibc's allocator up for a process whose memory is locked: call it first thing in
/// `main`, before any other thread allocates. glibc gives the free memory of its per-thread
/// arenas back with `MADV_DONTNEED`, which locked pages refuse, so every arena would keep the
/// largest size it ever had resident for the life of the daemon (a validation pass's
/// buffers, in whichever thread ran it). So: one arena, the main one, which shrinks by `brk`;
/// and every block from 128 KiB up mapped on its own and unmapped when freed (glibc's
/// default raises that threshold up to 32 MiB after the first such free, which would put the
/// large buffers of the next pass into the arena). No effect with another C library.
pub fn tune_allocator() {
    #[cfg(target_env = "gnu")]
    // SAFETY: mallopt only sets parameters of the allocator.
    unsafe {
        libc::mallopt(libc::M_ARENA_MAX, 1);
        libc::mallopt(libc::M_MMAP_THRESHOLD, 128 << 10);
    }
}

/// Lowers the calling thread's priority (nice + 10) for work nobody waits on, such as the
/// outline of a selected program: the API's threads and a job's pass come first. A thread
/// that cannot lower itself runs as it is.
pub fn lower_own_priority() {
    // SAFETY: plain syscalls on the calling thread (Linux: a thread id is a `PRIO_PROCESS` who).
    unsafe {
        let tid = libc::gettid() as libc::id_t;
        let now = libc::getpriority(libc::PRIO_PROCESS, tid);
        libc::setpriority(libc::PRIO_PROCESS, tid, (now + 10).min(19));
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
