//! The link to the RT thread: the command ring (API → RT), the snapshots the status thread
//! publishes, and the threads' start and shutdown. Every other part talks to the RT core
//! through it.

use std::sync::atomic::{AtomicBool, AtomicU32, Ordering};
use std::sync::{Arc, Mutex};
use std::thread::JoinHandle;
use std::time::Duration;

use tokio::sync::watch;

use super::pump::Pump;
use super::startup::StartError;
use super::{ClockKind, ControlError};
use crate::runtime::clock::{Clock, MonotonicClock};
use crate::runtime::config::Config;
use crate::runtime::job::JobLink;
use crate::runtime::rt::{self, MachineState, RtCommand, RtCoreConfig, RtParts, Snapshot};

/// Segment ring capacity (planner → RT).
const SEGMENT_RING: usize = 4096;
/// Command ring capacity (API → RT).
const COMMAND_RING: usize = 64;

pub(super) struct RtLink {
    /// The RT core's command ring, and how many commands were pushed into it.
    commands: Mutex<(rtrb::Producer<RtCommand>, u64)>,
    status: watch::Receiver<Snapshot>,
    rt_thread: Mutex<Option<JoinHandle<()>>>,
    pump_stop: Arc<AtomicBool>,
}

impl RtLink {
    /// Starts the RT thread on `bus` and the status thread (`pump`). Returns the link and the
    /// planner's end of the segment ring.
    pub(super) fn start(
        config: &Config,
        clock: ClockKind,
        bus: Box<dyn hal::DriveBus>,
        core: RtCoreConfig,
        pump: Pump,
    ) -> Result<(RtLink, JobLink), StartError> {
        let (cmd_tx, cmd_rx) = rtrb::RingBuffer::new(COMMAND_RING);
        let (seg_tx, seg_rx) = rtrb::RingBuffer::new(SEGMENT_RING);
        let initial = Snapshot::initial(config.axes.len(), core.start);
        let (snap_in, mut snap_out) = triple_buffer::triple_buffer(&initial);
        let planned_job = Arc::new(AtomicU32::new(0));
        let clock: Box<dyn Clock> = match clock {
            ClockKind::Monotonic => Box::new(MonotonicClock),
        };
        let parts = RtParts {
            bus,
            clock,
            commands: cmd_rx,
            segments: seg_rx,
            status: snap_in,
            planned_job: planned_job.clone(),
            core,
        };
        let rt_thread = spawn_rt_thread(config.rt.priority, config.rt.lock_memory, parts)?;

        let (status_tx, status_rx) = watch::channel(initial);
        let pump_stop = Arc::new(AtomicBool::new(false));
        let stop = pump_stop.clone();
        std::thread::Builder::new()
            .name("cnc-status".into())
            .stack_size(rt::THREAD_STACK_BYTES)
            .spawn(move || pump.run(&mut snap_out, &status_tx, &stop))
            .map_err(StartError::StatusThread)?;
        let link = RtLink {
            commands: Mutex::new((cmd_tx, 0)),
            status: status_rx,
            rt_thread: Mutex::new(Some(rt_thread)),
            pump_stop,
        };
        let jobs = JobLink {
            segments: Mutex::new(seg_tx),
            planned_job,
        };
        Ok((link, jobs))
    }

    /// Latest snapshot.
    pub(super) fn snapshot(&self) -> Snapshot {
        *self.status.borrow()
    }

    /// A receiver that sees every snapshot the pump publishes.
    pub(super) fn subscribe(&self) -> watch::Receiver<Snapshot> {
        self.status.clone()
    }

    pub(super) fn send(&self, cmd: RtCommand) -> Result<(), ControlError> {
        self.send_counted(cmd).map(|_| ())
    }

    /// Sends `cmd`; its number: the core has acted on it once `Snapshot::commands_taken`
    /// reaches it.
    pub(super) fn send_counted(&self, cmd: RtCommand) -> Result<u64, ControlError> {
        let mut ring = self.commands.lock().unwrap();
        ring.0.push(cmd).map_err(|_| ControlError::RtGone)?;
        ring.1 += 1;
        Ok(ring.1)
    }

    /// Commands sent so far (compare with `Snapshot::commands_taken`).
    pub(super) fn commands_sent(&self) -> u64 {
        self.commands.lock().unwrap().1
    }

    /// The latest snapshot if the machine is idle, the refusal to start otherwise.
    pub(super) fn idle_for_start(&self) -> Result<Snapshot, ControlError> {
        let snap = self.snapshot();
        if snap.state != MachineState::Idle {
            return Err(ControlError::WrongState(format!(
                "the machine is {:?}, it must be idle to start",
                snap.state
            )));
        }
        if let Some(why) = io_blocks_start(&snap) {
            return Err(ControlError::WrongState(why.into()));
        }
        Ok(snap)
    }

    /// Refuses `what` unless the machine is at rest (idle, faulted or enabling).
    pub(super) fn idle_or_refuse(&self, what: &str) -> Result<(), ControlError> {
        match self.snapshot().state {
            MachineState::Idle | MachineState::Fault | MachineState::Enabling => Ok(()),
            s => Err(ControlError::WrongState(format!(
                "{what} needs an idle machine; it is {s:?}"
            ))),
        }
    }

    /// Tells the RT thread to bring the axes to rest and end, and waits for it. Blocking.
    pub(super) fn shutdown_rt(&self) {
        let _ = self.send(RtCommand::Shutdown);
        if let Some(t) = self.rt_thread.lock().unwrap().take() {
            let _ = t.join();
        }
    }

    /// Ends the status thread once it has published the RT thread's final snapshot.
    pub(super) fn stop_pump(&self) {
        // Let the pump publish the final snapshot before it ends.
        std::thread::sleep(Duration::from_millis(10));
        self.pump_stop.store(true, Ordering::Relaxed);
    }
}

impl Drop for RtLink {
    fn drop(&mut self) {
        self.pump_stop.store(true, Ordering::Relaxed);
    }
}

/// Said once at start-up: the RT thread keeps computing the spindle speed (KŘR, the PLC
/// cells), but the setpoint has no drive to go to (issue #7).
pub(super) fn warn_without_spindle(bus: &dyn hal::DriveBus) {
    if !bus.has_spindle() {
        tracing::warn!(
            bus = bus.name(),
            "no spindle drive configured on the bus: the spindle speed is computed but not sent to any drive"
        );
    }
}

/// Starts the real-time thread on `parts` (priority and memory locking first).
fn spawn_rt_thread(
    priority: i32,
    lock_memory: bool,
    parts: RtParts,
) -> Result<JoinHandle<()>, StartError> {
    std::thread::Builder::new()
        .name("cnc-rt".into())
        .stack_size(rt::THREAD_STACK_BYTES)
        .spawn(move || {
            prepare_rt_thread(priority, lock_memory);
            rt::run(parts);
        })
        .map_err(StartError::RtThread)
}

/// Real-time priority and locked memory where permitted; a warning naming the grant otherwise.
fn prepare_rt_thread(priority: i32, lock: bool) {
    match rt::set_realtime_priority(priority) {
        Ok(()) => tracing::info!(priority, "real-time thread runs SCHED_FIFO"),
        Err(e) => tracing::warn!(
            "real-time thread runs without SCHED_FIFO priority {priority} ({e}): expect timing \
             jitter; run as root or grant CAP_SYS_NICE / LimitRTPRIO"
        ),
    }
    if lock {
        match rt::lock_memory() {
            Ok(()) => tracing::info!("memory locked (mlockall)"),
            Err(e) => tracing::warn!(
                "memory not locked ({e}): page faults may delay ticks; grant CAP_IPC_LOCK / \
                 LimitMEMLOCK"
            ),
        }
    }
}

/// What of the machine's inputs forbids a start (docs/io.md): the e-stop chain or the door
/// open, a limit switch reached.
pub(super) fn io_blocks_start(snap: &Snapshot) -> Option<&'static str> {
    let io = &snap.io;
    if io.estop_open {
        Some("the emergency-stop chain is open")
    } else if io.door_open {
        Some("the door is open")
    } else if io.limits.0 != 0 {
        Some("a hardware limit switch is reached: jog the axis away from it first")
    } else {
        None
    }
}
