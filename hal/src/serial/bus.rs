//! [`DriveBus`] over one serial port serving up to [`MAX_AXES`] axes of one drive unit. The
//! bus talks to the line only through [`SerialPort`] ([`TtyPort`] for a real tty or pty).
//!
//! Each tick ([`DriveBus::cycle`], in this order): read what arrived (the reply to the
//! previous tick's request), count a missing reply, watch the reference command, advance each
//! drive's CiA 402 phase machine (the one every bus shares, [`Drive`]: enable sequence,
//! statusword watch, a target that never jumps, safe state, orderly switch-off), write this
//! tick's request, report. The port is non-blocking
//! (zero timeout), so a tick never waits for the drive; a reply missing for
//! `reply_timeout_ticks` consecutive ticks is a fault. A port that reports hang-up or an I/O
//! error is closed; [`DriveBus::reset`] opens it again (the operator's reset after replugging).
//!
//! With a spindle drive configured the link speaks protocol version 2: each request carries
//! the spindle's controlword and target velocity, each reply its statusword and actual
//! velocity. The spindle goes through the same CiA 402 enable sequence and fault handling as
//! the axes. Without one it speaks version 1, as drive units without a spindle expect.
//!
//! With homing configured it speaks version 3: each reply carries the home switch inputs and
//! each request a reference command, by which the end of a reference run shifts the drive's
//! position (see [`Homing`]). A unit that answers only older versions is refused at start-up
//! with [`FaultReason::ProtocolVersion`].

use std::time::Duration;

use super::SerialError;
use super::frame::{self, Decoder, FrameError};
use super::message::{
    AxisRequest, HomeAction, HomeCommand, HomeResult, HomeStatus, Reply, Request,
};
use super::port::{LinkDown, SerialPort, TtyPort};
use crate::cia402::{Drive, DrivePhase, DriveSettings, FaultReaction, Setpoint, ShutdownMode, cw};
use crate::units::to_units;
use crate::{
    AxisFeedback, BusFault, CycleCommand, CycleFeedback, DriveBus, DriveState, FaultReason,
    MAX_AXES,
};

#[derive(Clone, Debug, PartialEq)]
pub struct SerialAxis {
    /// Reported in alarms (the drive unit's axis address).
    pub node_id: u8,
    pub increments_per_mm: f64,
    /// The axis's highest speed, mm/s. One tick's travel at it is the largest target step
    /// accepted when an enabled drive is handed from holding its own position over to the
    /// commanded positions.
    pub max_velocity_mm_s: f64,
}

impl SerialAxis {
    /// An axis with a speed limit of 200 mm/s.
    pub fn new(node_id: u8, increments_per_mm: f64) -> SerialAxis {
        SerialAxis {
            node_id,
            increments_per_mm,
            max_velocity_mm_s: 200.0,
        }
    }
}

/// The drive unit's spindle drive (CiA 402 velocity mode, protocol version 2).
#[derive(Clone, Debug, PartialEq)]
pub struct SerialSpindle {
    /// Reported in alarms (the drive unit's address of the spindle).
    pub node_id: u8,
    /// Drive velocity units per rpm.
    pub units_per_rpm: f64,
}

#[derive(Clone, Debug, PartialEq)]
pub struct SerialConfig {
    /// Device path (`/dev/ttyUSB0`, a pty, or a stable symlink to one).
    pub path: String,
    pub baud: u32,
    pub axes: Vec<SerialAxis>,
    /// The spindle drive of the unit, if it has one.
    pub spindle: Option<SerialSpindle>,
    /// Consecutive ticks without a valid reply before the link counts as silent.
    pub reply_timeout_ticks: u32,
    /// Ticks allowed for the enable sequence (and for the switch-off walk at shutdown).
    pub enable_timeout_ticks: u32,
    /// The tick period the caller calls `cycle` at.
    pub cycle: Duration,
    /// How the orderly shutdown switches the drives off.
    pub shutdown: ShutdownMode,
    /// What the drives do after a fault stop.
    pub fault_reaction: FaultReaction,
    /// The unit takes part in reference runs: speak protocol version 3.
    pub homing: bool,
}

impl SerialConfig {
    pub fn new(path: &str, axes: Vec<SerialAxis>) -> SerialConfig {
        SerialConfig {
            path: path.to_owned(),
            baud: 460_800,
            axes,
            spindle: None,
            reply_timeout_ticks: 25,
            enable_timeout_ticks: 500,
            cycle: Duration::from_millis(4),
            shutdown: ShutdownMode::Disable,
            fault_reaction: FaultReaction::QuickStop,
            homing: false,
        }
    }
}

/// The master of one drive unit over a [`SerialPort`] (a [`TtyPort`] unless a test supplies
/// its own).
pub struct SerialBus<P: SerialPort = TtyPort> {
    cfg: SerialConfig,
    port: P,
    /// False after a [`LinkDown`] until the operator's reset opens the port again.
    port_open: bool,
    decoder: Decoder,
    /// The axes' drives (`[..n_axes]`), then the spindle's if configured.
    axes: Vec<Drive>,
    n_axes: usize,
    tick: u64,
    seq: u8,
    /// The last request still waits for its reply.
    awaiting: bool,
    missing: u32,
    corrupt_since_reply: u32,
    have_feedback: bool,
    link_fault: Option<FaultReason>,
    rx: [u8; 256],
    homing: Homing,
    shutting_down: bool,
}

/// Without a version 3 reply, every this many ticks of silence the request goes out in the
/// older version, to tell an old unit (which answers it) from a silent one.
const PROBE_EVERY_TICKS: u32 = 3;
/// Probes answered by a unit that never answered version 3: it is an old unit.
const PROBE_ANSWERS: u32 = 3;
/// Ticks the drive has to acknowledge a reference command.
pub const HOME_ACK_TIMEOUT_TICKS: u64 = 50;

/// A reference command sent until the drive acknowledges it.
#[derive(Clone, Copy, Debug)]
struct PendingHome {
    id: u8,
    axis: usize,
    shift_increments: i32,
    since_tick: u64,
}

/// Protocol version 3 state. The reference command is idempotent by its id: the controller
/// repeats it in every request until a reply carries the id, so a lost frame neither loses
/// nor doubles the shift. Replies without the id still report positions in the old reference;
/// they are shifted here, so the controller sees one consistent position (no jump).
#[derive(Clone, Copy, Debug, Default)]
struct Homing {
    /// Some reply arrived in version 3.
    v3_seen: bool,
    /// Older-version replies to probes while no version 3 reply arrived.
    probe_answers: u32,
    /// The last request went out in the older version.
    probing: bool,
    /// Home switch inputs of the last reply.
    switches: u8,
    /// The id the drive acknowledged last.
    acked_id: u8,
    pending: Option<PendingHome>,
}

impl SerialBus<TtyPort> {
    /// Opens the tty of `cfg.path`. Nothing is sent before the first cycle.
    pub fn open(cfg: SerialConfig) -> Result<SerialBus<TtyPort>, SerialError> {
        check_config(&cfg)?;
        let port = TtyPort::open(&cfg.path, cfg.baud)?;
        Ok(SerialBus::with_port(port, cfg))
    }
}

/// Checks the settings the bus cannot run with.
fn check_config(cfg: &SerialConfig) -> Result<(), SerialError> {
    if cfg.axes.is_empty() || cfg.axes.len() > MAX_AXES {
        return Err(SerialError::AxisCount {
            count: cfg.axes.len(),
            path: cfg.path.clone(),
        });
    }
    if let Some(axis) = cfg
        .axes
        .iter()
        .position(|a| !(a.increments_per_mm.is_finite() && a.increments_per_mm > 0.0))
    {
        return Err(SerialError::AxisScale { axis });
    }
    if let Some(sp) = &cfg.spindle
        && !(sp.units_per_rpm.is_finite() && sp.units_per_rpm > 0.0)
    {
        return Err(SerialError::SpindleScale);
    }
    Ok(())
}

impl<P: SerialPort> SerialBus<P> {
    /// The bus over an open `port` (`cfg.path` and `cfg.baud` only name it).
    pub fn new(port: P, cfg: SerialConfig) -> Result<SerialBus<P>, SerialError> {
        check_config(&cfg)?;
        Ok(SerialBus::with_port(port, cfg))
    }

    fn with_port(port: P, cfg: SerialConfig) -> SerialBus<P> {
        let settings = |setpoint, max_step_increments| DriveSettings {
            shutdown: cfg.shutdown,
            ..DriveSettings::new(
                setpoint,
                max_step_increments,
                u64::from(cfg.enable_timeout_ticks),
            )
        };
        let tick_s = cfg.cycle.as_secs_f64();
        let mut axes: Vec<Drive> = cfg
            .axes
            .iter()
            .map(|a| {
                let step = a.max_velocity_mm_s * a.increments_per_mm * tick_s;
                Drive::new(settings(Setpoint::Position, step))
            })
            .collect();
        if cfg.spindle.is_some() {
            axes.push(Drive::new(settings(Setpoint::Velocity, 1.0)));
        }
        SerialBus {
            n_axes: cfg.axes.len(),
            axes,
            cfg,
            port,
            port_open: true,
            decoder: Decoder::default(),
            tick: 0,
            seq: 0,
            awaiting: false,
            missing: 0,
            corrupt_since_reply: 0,
            have_feedback: false,
            link_fault: None,
            rx: [0; 256],
            homing: Homing::default(),
            shutting_down: false,
        }
    }

    fn link_down(&mut self) {
        self.port.close();
        self.port_open = false;
        self.link_fault = Some(FaultReason::LinkDown);
    }

    /// Reads everything waiting; applies the reply to the last request.
    fn receive(&mut self) {
        // Bounded: a babbling line cannot hold the tick.
        for _ in 0..8 {
            if !self.port_open {
                return;
            }
            match self.port.try_read(&mut self.rx) {
                Ok(0) => return,
                Ok(n) => self.on_bytes(n),
                Err(LinkDown) => {
                    self.link_down();
                    return;
                }
            }
        }
    }

    /// Decodes the `n` bytes read into `rx`: the reply to this request, corrupt frames.
    fn on_bytes(&mut self, n: usize) {
        let mut reply = None;
        let mut corrupt = 0;
        let seq = self.seq;
        self.decoder.feed(&self.rx[..n], |r| match r {
            Ok(p) => match Reply::decode(p) {
                Some(y) if y.seq == seq => reply = Some(y),
                // A late reply to an earlier request, or a malformed one.
                Some(_) => {}
                None => corrupt += 1,
            },
            Err(FrameError::Crc | FrameError::Encoding | FrameError::TooLong) => corrupt += 1,
        });
        self.corrupt_since_reply += corrupt;
        if let Some(y) = reply {
            self.on_reply(&y);
        }
    }

    /// The reply to this tick's request: an older version answering a probe, or the feedback
    /// when it has our axes and, exactly when we have one, the spindle.
    fn on_reply(&mut self, y: &Reply) {
        let spindle = self.axes.len() > self.n_axes;
        if self.cfg.homing && y.home.is_none() {
            self.probe_answered(y);
        } else if usize::from(y.axes) == self.n_axes
            && y.spindle.is_some() == spindle
            && y.home.is_some() == self.cfg.homing
        {
            let records = y.axis[..self.n_axes].iter().chain(y.spindle.as_ref());
            for (d, r) in self.axes.iter_mut().zip(records) {
                d.on_status(r.statusword, r.position_increments);
                d.set_error_code(r.error_code);
            }
            if let Some(h) = y.home {
                self.home_status(h);
            }
            self.awaiting = false;
            self.missing = 0;
            self.corrupt_since_reply = 0;
            self.have_feedback = true;
        }
    }

    /// Counts a tick without the awaited reply; too many make the link silent (or corrupt).
    fn count_missing_reply(&mut self) {
        if !self.awaiting {
            return;
        }
        self.missing += 1;
        if self.missing > self.cfg.reply_timeout_ticks && self.link_fault.is_none() {
            self.link_fault = Some(if self.corrupt_since_reply > 0 {
                FaultReason::CorruptFrames
            } else {
                FaultReason::Timeout
            });
        }
    }

    /// This tick's setpoint of drive `i` in drive units: an axis position, or the spindle
    /// speed (a setpoint that is not a number stops the spindle).
    fn target_of(&self, i: usize, cmd: &CycleCommand) -> i32 {
        match self.cfg.axes.get(i) {
            Some(c) => to_units(cmd.positions_mm[i], c.increments_per_mm),
            None => {
                let rpm = if cmd.spindle_rpm.is_finite() {
                    cmd.spindle_rpm
                } else {
                    0.0
                };
                to_units(rpm, self.spindle_units_per_rpm())
            }
        }
    }

    /// Advances every drive by one tick; `fresh`: this tick's reply arrived.
    fn update_drives(&mut self, cmd: &CycleCommand, fresh: bool) {
        let tick = self.tick;
        for i in 0..self.axes.len() {
            let target = self.target_of(i, cmd);
            let d = &mut self.axes[i];
            match (self.link_fault, d.phase()) {
                (None, _) | (Some(_), DrivePhase::Off) => {}
                // No answer will come: the walk down ends here.
                (Some(_), DrivePhase::PoweringDown { .. }) => d.switch_off(),
                // The drive is unreachable or unreliable: hold, and ask it to switch off.
                (Some(reason), _) => d.fault(reason),
            }
            d.tick(tick, fresh, target);
        }
    }

    fn send_request(&mut self) {
        if !self.port_open {
            return;
        }
        self.seq = self.seq.wrapping_add(1);
        let record = |d: &Drive| AxisRequest {
            controlword: d.controlword(),
            target_increments: d.target_increments(),
        };
        let probe = self.probe_due();
        self.homing.probing = probe;
        let mut req = Request {
            seq: self.seq,
            axes: self.n_axes as u8,
            axis: [AxisRequest::default(); MAX_AXES],
            spindle: self.axes.get(self.n_axes).map(record),
            home: (self.cfg.homing && !probe).then(|| self.home_command()),
        };
        for (r, a) in req.axis.iter_mut().zip(&self.axes[..self.n_axes]) {
            *r = record(a);
        }
        if probe {
            // The probe must not switch anything on in a unit we are about to refuse.
            for r in req.axis.iter_mut().chain(req.spindle.as_mut()) {
                r.controlword = cw::DISABLE_VOLTAGE;
            }
        }
        let mut payload = [0u8; 64];
        let n = req.encode(&mut payload);
        let mut out = [0u8; frame::MAX_FRAME];
        let len = frame::encode(&payload[..n], &mut out);
        match self.port.write(&out[..len]) {
            Ok(()) => self.awaiting = true,
            Err(LinkDown) => self.link_down(),
        }
    }

    /// Whether this request goes out in the older version (see [`PROBE_EVERY_TICKS`]).
    fn probe_due(&self) -> bool {
        self.cfg.homing
            && !self.homing.v3_seen
            && self.missing > 0
            && self.missing.is_multiple_of(PROBE_EVERY_TICKS)
    }

    /// An older-version reply while homing needs version 3: the answer to a probe. A unit
    /// that answers probes but never version 3 is an old unit: refused, clearly.
    fn probe_answered(&mut self, y: &Reply) {
        if !self.homing.probing {
            return;
        }
        self.awaiting = false;
        self.missing = 0;
        self.corrupt_since_reply = 0;
        self.homing.probe_answers += 1;
        if !self.homing.v3_seen && self.homing.probe_answers >= PROBE_ANSWERS {
            self.link_fault = Some(FaultReason::ProtocolVersion {
                drive: y.version(),
                needed: 3,
            });
        }
    }

    /// The reference command of this request: the pending one, or none (with the id the drive
    /// acknowledged last, so it changes nothing).
    fn home_command(&self) -> HomeCommand {
        match self.homing.pending {
            Some(p) => HomeCommand {
                action: HomeAction::SetReference,
                id: p.id,
                axis: p.axis as u8,
                shift_increments: p.shift_increments,
            },
            None => HomeCommand {
                id: self.homing.acked_id,
                ..HomeCommand::default()
            },
        }
    }

    /// Switches and acknowledgement of a version 3 reply (its positions already stored).
    fn home_status(&mut self, h: HomeStatus) {
        let first = !self.homing.v3_seen;
        self.homing.v3_seen = true;
        self.homing.switches = h.switches;
        let Some(p) = self.homing.pending else {
            if first {
                // Continue from the drive's last id (it keeps it over a controller restart).
                self.homing.acked_id = h.id;
            }
            return;
        };
        if h.id != p.id {
            // Sent before the drive took the new reference: shift it here.
            let d = &mut self.axes[p.axis];
            d.set_actual_increments(d.actual_increments().saturating_add(p.shift_increments));
            return;
        }
        self.homing.acked_id = h.id;
        self.homing.pending = None;
        if h.result == HomeResult::Refused {
            self.axes[p.axis].fault(FaultReason::HomingRefused);
        }
    }

    /// A reference command not acknowledged in time faults its axis.
    fn check_home_ack(&mut self) {
        if let Some(p) = self.homing.pending
            && self.tick - p.since_tick > HOME_ACK_TIMEOUT_TICKS
        {
            self.homing.pending = None;
            self.axes[p.axis].fault(FaultReason::HomingTimeout);
        }
    }

    fn spindle_units_per_rpm(&self) -> f64 {
        self.cfg.spindle.as_ref().map_or(1.0, |s| s.units_per_rpm)
    }

    fn link_scope(&self) -> (Option<u8>, Option<u8>) {
        // A one-axis link names its axis; a multi-axis link concerns all its axes.
        if self.axes.len() == 1 {
            (Some(0), Some(self.cfg.axes[0].node_id))
        } else {
            (None, None)
        }
    }

    fn state_of(&self, d: &Drive) -> DriveState {
        match d.phase() {
            _ if self.link_fault.is_some() => DriveState::Fault,
            DrivePhase::Off | DrivePhase::Stopped | DrivePhase::PoweringDown { .. } => {
                DriveState::Disabled
            }
            DrivePhase::Enabling { .. } => DriveState::Enabling,
            DrivePhase::Enabled => DriveState::Operational,
            DrivePhase::Faulted(_) => DriveState::Fault,
        }
    }

    fn fill_feedback(&self, feedback: &mut CycleFeedback) {
        for ((fb, a), c) in feedback.axes.iter_mut().zip(&self.axes).zip(&self.cfg.axes) {
            *fb = AxisFeedback {
                position_mm: f64::from(a.actual_increments()) / c.increments_per_mm,
                state: self.state_of(a),
            };
        }
        (feedback.spindle_rpm, feedback.spindle_state) = match self.axes.get(self.n_axes) {
            Some(a) => {
                let state = self.state_of(a);
                let rpm = if state == DriveState::Operational {
                    f64::from(a.actual_increments()) / self.spindle_units_per_rpm()
                } else {
                    0.0
                };
                (rpm, state)
            }
            None => (0.0, DriveState::Disabled),
        };
    }

    /// The fault to report this tick: the link's, else the first faulted drive's.
    fn first_fault(&self) -> Result<(), BusFault> {
        if let Some(reason) = self.link_fault {
            let (axis, node) = self.link_scope();
            return Err(BusFault { axis, node, reason });
        }
        for (i, d) in self.axes.iter().enumerate() {
            if let Some(reason) = d.fault_reason() {
                let (axis, node) = match (&self.cfg.axes.get(i), &self.cfg.spindle) {
                    (Some(c), _) => (i as u8, c.node_id),
                    (None, Some(sp)) => (crate::SPINDLE_AXIS, sp.node_id),
                    (None, None) => (i as u8, 0),
                };
                return Err(BusFault {
                    axis: Some(axis),
                    node: Some(node),
                    reason,
                });
            }
        }
        Ok(())
    }
}

impl<P: SerialPort> DriveBus for SerialBus<P> {
    fn name(&self) -> &str {
        &self.cfg.path
    }

    fn axes(&self) -> usize {
        self.n_axes
    }

    fn has_spindle(&self) -> bool {
        self.axes.len() > self.n_axes
    }

    /// Receive the reply, count a missing one, watch the reference command, advance the
    /// drives, send this tick's request, report.
    fn cycle(&mut self, cmd: &CycleCommand, feedback: &mut CycleFeedback) -> Result<(), BusFault> {
        self.tick += 1;
        let was_awaiting = self.awaiting;
        self.receive();
        let fresh = was_awaiting && !self.awaiting;
        self.count_missing_reply();
        self.check_home_ack();
        self.update_drives(cmd, fresh);
        self.send_request();
        self.fill_feedback(feedback);
        self.first_fault()
    }

    fn enable(&mut self) {
        if self.shutting_down {
            return;
        }
        let tick = self.tick;
        for d in &mut self.axes {
            if d.phase() == DrivePhase::Off {
                d.begin_enable(tick);
            }
        }
    }

    /// Every drive still on walks down (07h → 06h → 00h, or 02h → 00h) on the unit's replies;
    /// a link that is down ends the walk at once (the unit's watchdog switches it off).
    fn shutdown(&mut self) {
        if self.shutting_down {
            return;
        }
        self.shutting_down = true;
        let tick = self.tick;
        for d in &mut self.axes {
            if d.phase() != DrivePhase::Off {
                d.begin_power_down(tick);
            }
        }
    }

    fn is_shut_down(&self) -> bool {
        self.shutting_down && self.axes.iter().all(|d| d.phase() == DrivePhase::Off)
    }

    /// After a fault stop with the healthy axes at rest: every drive still enabled (or on its
    /// way) goes to the configured safe state, its target holding where it stands.
    fn safe_state(&mut self) {
        let Some(controlword) = self.cfg.fault_reaction.controlword() else {
            return;
        };
        for d in &mut self.axes {
            if matches!(d.phase(), DrivePhase::Enabling { .. } | DrivePhase::Enabled) {
                d.stop(controlword);
            }
        }
    }

    fn supports_homing(&self) -> bool {
        self.cfg.homing
    }

    fn home_switch(&self, axis: usize) -> bool {
        self.cfg.homing && axis < self.n_axes && self.homing.switches & (1 << axis) != 0
    }

    /// Sends the reference command: the drive's position shifts by `reference − trigger`
    /// (rounded to increments) from the next request on, repeated until acknowledged. One
    /// command at a time: a second one before the first is acknowledged is refused.
    fn set_home(&mut self, axis: usize, trigger_mm: f64, reference_mm: f64) {
        let Some(c) = self.cfg.axes.get(axis).filter(|_| self.cfg.homing) else {
            return;
        };
        if self.homing.pending.is_some() {
            self.axes[axis].fault(FaultReason::HomingRefused);
            return;
        }
        let inc = |mm: f64| {
            (mm * c.increments_per_mm)
                .round()
                .clamp(f64::from(i32::MIN), f64::from(i32::MAX)) as i64
        };
        let shift = (inc(reference_mm) - inc(trigger_mm))
            .clamp(i64::from(i32::MIN), i64::from(i32::MAX)) as i32;
        let id = match self.homing.acked_id.wrapping_add(1) {
            0 => 1,
            n => n,
        };
        self.homing.pending = Some(PendingHome {
            id,
            axis,
            shift_increments: shift,
            since_tick: self.tick,
        });
    }

    fn reset(&mut self) {
        if self.shutting_down {
            return;
        }
        if !self.port_open {
            // Reopening allocates and may take a moment; it happens only on the operator's
            // reset, never in `cycle`. If the port is still missing the fault stays.
            if self.port.reopen().is_err() {
                return;
            }
            self.port_open = true;
        }
        self.decoder.clear();
        self.link_fault = None;
        self.awaiting = false;
        self.missing = 0;
        self.corrupt_since_reply = 0;
        // The unit may have been swapped: find out its version again. A reference command
        // still pending is dropped (its axis is no longer homed: the fault cleared that).
        self.homing = Homing {
            acked_id: self.homing.acked_id,
            ..Homing::default()
        };
        let tick = self.tick;
        // Every axis goes through the enable sequence again: a drive that lost its link has
        // switched itself off, one that did not is confirmed enabled on the first reply.
        for d in &mut self.axes {
            d.begin_enable(tick);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::cia402::{self, PowerState};
    use crate::serial::message::AxisReply;
    use std::sync::{Arc, Mutex};

    /// Both directions of an in-memory line, and whether it hung up.
    #[derive(Default)]
    struct Line {
        to_drive: Vec<u8>,
        to_master: Vec<u8>,
        hung_up: bool,
    }

    /// The master's end of the in-memory line.
    #[derive(Clone, Default)]
    struct MemPort(Arc<Mutex<Line>>);

    impl SerialPort for MemPort {
        fn try_read(&mut self, buf: &mut [u8]) -> Result<usize, LinkDown> {
            let mut line = self.0.lock().unwrap();
            if line.hung_up {
                return Err(LinkDown);
            }
            let n = line.to_master.len().min(buf.len());
            buf[..n].copy_from_slice(&line.to_master[..n]);
            line.to_master.drain(..n);
            Ok(n)
        }

        fn write(&mut self, frame: &[u8]) -> Result<(), LinkDown> {
            let mut line = self.0.lock().unwrap();
            if line.hung_up {
                return Err(LinkDown);
            }
            line.to_drive.extend_from_slice(frame);
            Ok(())
        }

        fn close(&mut self) {}

        fn reopen(&mut self) -> Result<(), SerialError> {
            if self.0.lock().unwrap().hung_up {
                return Err(SerialError::Open {
                    path: "mem".into(),
                    reason: "unplugged".into(),
                });
            }
            Ok(())
        }
    }

    /// The test plays the drive at the other end of the line: it answers requests by hand.
    struct Unit {
        line: MemPort,
        decoder: Decoder,
    }

    impl Unit {
        /// Reads the last request sent and answers what `reply` makes of it (nothing on
        /// `None`).
        fn answer_with(
            &mut self,
            reply: impl FnOnce(&Request) -> Option<Reply>,
        ) -> Option<Request> {
            let bytes = std::mem::take(&mut self.line.0.lock().unwrap().to_drive);
            let mut got = None;
            self.decoder.feed(&bytes, |r| {
                if let Ok(p) = r {
                    got = Request::decode(p);
                }
            });
            let req = got?;
            if let Some(y) = reply(&req) {
                let mut p = [0u8; 64];
                let n = y.encode(&mut p);
                let mut f = [0u8; frame::MAX_FRAME];
                let len = frame::encode(&p[..n], &mut f);
                self.line
                    .0
                    .lock()
                    .unwrap()
                    .to_master
                    .extend_from_slice(&f[..len]);
            }
            Some(req)
        }

        /// Answers the last request for one axis with `statusword` at `position`.
        fn answer(&mut self, statusword: u16, position: i32) -> Option<Request> {
            self.answer_with(|req| {
                let mut y = v1_reply(req, position);
                y.axis[0].statusword = statusword;
                Some(y)
            })
        }

        fn hang_up(&self, hung_up: bool) {
            self.line.0.lock().unwrap().hung_up = hung_up;
        }
    }

    /// A version 1 reply of one enabled axis at `position`.
    fn v1_reply(req: &Request, position: i32) -> Reply {
        let mut y = Reply {
            seq: req.seq,
            axes: 1,
            axis: [AxisReply::default(); MAX_AXES],
            spindle: None,
            home: None,
        };
        y.axis[0] = AxisReply {
            statusword: PowerState::OperationEnabled.statusword_bits(),
            position_increments: position,
            error_code: 0,
        };
        y
    }

    /// A version 3 reply of one enabled axis at `position`.
    fn v3_reply(req: &Request, position: i32, home: HomeStatus) -> Option<Reply> {
        Some(Reply {
            home: Some(home),
            ..v1_reply(req, position)
        })
    }

    fn setup() -> (SerialBus<MemPort>, Unit) {
        setup_with(false)
    }

    fn setup_with(homing: bool) -> (SerialBus<MemPort>, Unit) {
        let line = MemPort::default();
        let cfg = SerialConfig {
            homing,
            ..SerialConfig::new("mem", vec![SerialAxis::new(4, 100.0)])
        };
        let bus = SerialBus::new(line.clone(), cfg).unwrap();
        let drive = Unit {
            line,
            decoder: Decoder::default(),
        };
        (bus, drive)
    }

    #[test]
    fn a_bad_configuration_is_refused_with_its_code() {
        let axis = |increments_per_mm| SerialAxis::new(1, increments_per_mm);
        let open = |axes: Vec<SerialAxis>| {
            SerialBus::new(MemPort::default(), SerialConfig::new("mem", axes))
                .err()
                .map(|e| e.code())
        };
        assert_eq!(open(vec![]), Some("serial_axis_count"));
        assert_eq!(open(vec![axis(1.0), axis(0.0)]), Some("serial_axis_scale"));
        assert_eq!(open(vec![axis(1.0)]), None);
        let cfg = SerialConfig {
            spindle: Some(SerialSpindle {
                node_id: 2,
                units_per_rpm: f64::NAN,
            }),
            ..SerialConfig::new("mem", vec![axis(1.0)])
        };
        let e = SerialBus::new(MemPort::default(), cfg).err().unwrap();
        assert_eq!(e.code(), "serial_spindle_scale");
    }

    #[test]
    fn enables_follows_and_times_out_on_silence() {
        let (mut bus, mut drive) = setup();
        bus.enable();
        let mut fb = CycleFeedback::default();
        let mut cmd = CycleCommand::default();
        cmd.positions_mm[0] = 1.5;
        let mut state = PowerState::SwitchOnDisabled;
        let mut last_cw = 0;
        for _ in 0..12 {
            bus.cycle(&cmd, &mut fb).unwrap();
            let req = drive.answer(state.statusword_bits(), 100).unwrap();
            let c = req.axis[0].controlword;
            state = cia402::apply_controlword(state, last_cw, c);
            last_cw = c;
        }
        assert_eq!(state, PowerState::OperationEnabled);
        bus.cycle(&cmd, &mut fb).unwrap();
        assert_eq!(fb.axes[0].state, DriveState::Operational);
        assert!((fb.axes[0].position_mm - 1.0).abs() < 1e-9);
        let req = drive.answer(state.statusword_bits(), 150).unwrap();
        assert_eq!(req.axis[0].target_increments, 150);

        // Silence: exactly reply_timeout_ticks ticks pass without a fault, then Timeout.
        let mut ticks = 0;
        let e = loop {
            ticks += 1;
            if let Err(e) = bus.cycle(&cmd, &mut fb) {
                break e;
            }
        };
        assert_eq!(ticks, 27, "the first tick still reads the last reply");
        assert_eq!(e.reason, FaultReason::Timeout);
        assert_eq!((e.axis, e.node), (Some(0), Some(4)));
    }

    #[test]
    fn hang_up_is_link_down_and_reset_keeps_it_until_the_port_returns() {
        let (mut bus, mut drive) = setup();
        bus.enable();
        drive.hang_up(true);
        let mut fb = CycleFeedback::default();
        let cmd = CycleCommand::default();
        let e = bus.cycle(&cmd, &mut fb).unwrap_err();
        assert_eq!(e.reason, FaultReason::LinkDown);
        assert_eq!(fb.axes[0].state, DriveState::Fault);
        // Still unplugged: the reset cannot reopen the port, the fault stays.
        bus.reset();
        let e = bus.cycle(&cmd, &mut fb).unwrap_err();
        assert_eq!(e.reason, FaultReason::LinkDown);
        assert!(
            drive.answer(0, 0).is_none(),
            "nothing is sent on a closed port"
        );
        // Plugged in again: the reset reopens it and the drive is enabled again.
        drive.hang_up(false);
        bus.reset();
        bus.cycle(&cmd, &mut fb).unwrap();
        assert_eq!(fb.axes[0].state, DriveState::Enabling);
        drive.answer(PowerState::SwitchOnDisabled.statusword_bits(), 0);
        bus.cycle(&cmd, &mut fb).unwrap();
        let req = drive.answer(0, 0).unwrap();
        assert_eq!(req.axis[0].controlword, cw::SHUTDOWN);
    }

    /// Version 3: the switch input reaches `home_switch`; the reference command shifts the
    /// reported position at once (replies still in the old reference are shifted by the
    /// controller) and is repeated until acknowledged; a refusal faults the axis.
    #[test]
    fn reference_command_is_repeated_until_acknowledged_and_a_refusal_faults_the_axis() {
        let (mut bus, mut drive) = setup_with(true);
        bus.enable();
        let mut fb = CycleFeedback::default();
        let mut cmd = CycleCommand::default();
        cmd.positions_mm[0] = 1.0;
        let pressed = HomeStatus {
            switches: 1,
            ..HomeStatus::default()
        };
        for _ in 0..3 {
            bus.cycle(&cmd, &mut fb).unwrap();
            let req = drive.answer_with(|r| v3_reply(r, 100, pressed)).unwrap();
            assert_eq!(req.version(), 3);
        }
        bus.cycle(&cmd, &mut fb).unwrap();
        assert_eq!(fb.axes[0].state, DriveState::Operational);
        assert!(bus.home_switch(0) && !bus.home_switch(1));
        // The switch was met at 1 mm; it becomes -2 mm: the drive shifts by -300 increments.
        bus.set_home(0, 1.0, -2.0);
        cmd.positions_mm[0] = -2.0;
        // The drive has not seen the command yet (its reply is in the old reference).
        let req = drive.answer_with(|r| v3_reply(r, 100, pressed)).unwrap();
        assert_eq!(req.home.unwrap().action, HomeAction::None);
        bus.cycle(&cmd, &mut fb).unwrap();
        assert!((fb.axes[0].position_mm + 2.0).abs() < 1e-9, "{fb:?}");
        // Its reply is lost: the command comes again with the same id.
        let first = drive.answer_with(|_| None).unwrap().home.unwrap();
        bus.cycle(&cmd, &mut fb).unwrap();
        assert!((fb.axes[0].position_mm + 2.0).abs() < 1e-9, "{fb:?}");
        let acked = HomeStatus {
            id: first.id,
            ..pressed
        };
        let again = drive.answer_with(|r| v3_reply(r, -200, acked)).unwrap();
        assert_eq!(again.home, Some(first));
        assert_eq!(
            (
                first.action,
                first.shift_increments,
                again.axis[0].target_increments
            ),
            (HomeAction::SetReference, -300, -200)
        );
        bus.cycle(&cmd, &mut fb).unwrap();
        assert!((fb.axes[0].position_mm + 2.0).abs() < 1e-9, "{fb:?}");
        let idle = drive.answer_with(|r| v3_reply(r, -200, acked)).unwrap();
        assert_eq!(idle.home.unwrap().action, HomeAction::None);

        // The next command is refused: a fault naming the axis.
        bus.cycle(&cmd, &mut fb).unwrap();
        bus.set_home(0, -2.0, 0.0);
        drive.answer_with(|r| v3_reply(r, -200, acked));
        bus.cycle(&cmd, &mut fb).unwrap();
        let refused = HomeStatus {
            id: first.id.wrapping_add(1),
            result: HomeResult::Refused,
            ..pressed
        };
        drive.answer_with(|r| v3_reply(r, 0, refused));
        let e = bus.cycle(&cmd, &mut fb).unwrap_err();
        assert_eq!(
            (e.reason, e.axis, e.node),
            (FaultReason::HomingRefused, Some(0), Some(4))
        );
    }

    #[test]
    fn an_unacknowledged_reference_command_times_out() {
        let (mut bus, mut drive) = setup_with(true);
        bus.enable();
        let mut fb = CycleFeedback::default();
        let cmd = CycleCommand::default();
        for _ in 0..4 {
            bus.cycle(&cmd, &mut fb).unwrap();
            drive.answer_with(|r| v3_reply(r, 0, HomeStatus::default()));
        }
        bus.set_home(0, 0.0, 1.0);
        let mut ticks = 0;
        let e = loop {
            ticks += 1;
            match bus.cycle(&cmd, &mut fb) {
                Ok(()) => drive.answer_with(|r| v3_reply(r, 0, HomeStatus::default())),
                Err(e) => break e,
            };
        };
        assert_eq!(ticks, HOME_ACK_TIMEOUT_TICKS + 1);
        assert_eq!(
            (e.reason, e.axis, e.node),
            (FaultReason::HomingTimeout, Some(0), Some(4))
        );
    }

    /// A unit of an older version answers only the probes: refused at start-up, clearly.
    #[test]
    fn an_old_unit_is_refused_when_homing_needs_version_3() {
        let (mut bus, mut drive) = setup_with(true);
        bus.enable();
        let mut fb = CycleFeedback::default();
        let cmd = CycleCommand::default();
        let mut probes = 0;
        let e = loop {
            if let Err(e) = bus.cycle(&cmd, &mut fb) {
                break e;
            }
            let req = drive
                .answer_with(|r| {
                    let mut y = v3_reply(r, 0, HomeStatus::default())?;
                    y.home = None;
                    (r.version() == 1).then_some(y)
                })
                .unwrap();
            if req.version() == 1 {
                probes += 1;
                assert_eq!(req.axis[0].controlword, cw::DISABLE_VOLTAGE);
            }
        };
        assert_eq!(probes, PROBE_ANSWERS);
        assert_eq!(
            e.reason,
            FaultReason::ProtocolVersion {
                drive: 1,
                needed: 3
            }
        );
        assert!(e.to_string().contains("version 1, homing needs version 3"));
    }

    /// The drive unit's CiA 402 power stage of axis 0, standing at `position`: it answers
    /// each request with its state, then takes the request's controlword.
    struct Stage {
        state: PowerState,
        last_cw: u16,
        position: i32,
    }

    impl Stage {
        fn new(position: i32) -> Stage {
            Stage {
                state: PowerState::SwitchOnDisabled,
                last_cw: 0,
                position,
            }
        }

        /// One tick of the bus and the unit's answer to its request.
        fn exchange(
            &mut self,
            bus: &mut SerialBus<MemPort>,
            unit: &mut Unit,
            cmd: &CycleCommand,
        ) -> (Result<(), BusFault>, CycleFeedback, AxisRequest) {
            let mut fb = CycleFeedback::default();
            let r = bus.cycle(cmd, &mut fb);
            let req = unit
                .answer(self.state.statusword_bits(), self.position)
                .unwrap();
            let c = req.axis[0].controlword;
            self.state = cia402::apply_controlword(self.state, self.last_cw, c);
            self.last_cw = c;
            (r, fb, req.axis[0])
        }

        /// Ticks until the drive is enabled (and the bus saw it).
        fn enable(&mut self, bus: &mut SerialBus<MemPort>, unit: &mut Unit, cmd: &CycleCommand) {
            for _ in 0..12 {
                self.exchange(bus, unit, cmd).0.unwrap();
            }
            assert_eq!(self.state, PowerState::OperationEnabled);
        }
    }

    /// The controller still commands 0 mm while the drive stands at 3 mm (it takes its
    /// commanded position from the drives once all are enabled): the target holds, no jump.
    #[test]
    fn an_enabled_drive_holds_until_the_command_comes_within_one_tick() {
        let (mut bus, mut unit) = setup();
        bus.enable();
        let mut stage = Stage::new(300);
        let mut cmd = CycleCommand::default();
        stage.enable(&mut bus, &mut unit, &cmd);
        let (r, fb, req) = stage.exchange(&mut bus, &mut unit, &cmd);
        r.unwrap();
        assert_eq!(fb.axes[0].state, DriveState::Operational);
        assert_eq!(req.target_increments, 300);
        // Within one tick at 200 mm/s (80 increments): taken over, then followed.
        for (mm, increments) in [(3.5, 350), (4.2, 420), (0.0, 0)] {
            cmd.positions_mm[0] = mm;
            let (_, _, req) = stage.exchange(&mut bus, &mut unit, &cmd);
            assert_eq!(req.target_increments, increments);
        }
    }

    /// After a fault stop the drive quick-stops and holds; a reset enables it again; the
    /// shutdown walks it down 07h → 06h → 00h and nothing enables it after that.
    #[test]
    fn safe_state_holds_and_shutdown_walks_the_drive_down() {
        let (mut bus, mut unit) = setup();
        bus.enable();
        let mut stage = Stage::new(120);
        let cmd = CycleCommand::default();
        stage.enable(&mut bus, &mut unit, &cmd);
        bus.safe_state();
        let (r, fb, req) = stage.exchange(&mut bus, &mut unit, &cmd);
        r.unwrap();
        assert_eq!(req.controlword, cw::QUICK_STOP_CMD);
        assert_eq!(req.target_increments, 120);
        assert_eq!(fb.axes[0].state, DriveState::Disabled);
        assert_eq!(stage.state, PowerState::QuickStopActive);
        bus.reset();
        stage.enable(&mut bus, &mut unit, &cmd);

        bus.shutdown();
        let mut sent = Vec::new();
        while !bus.is_shut_down() {
            assert!(sent.len() < 10, "no end: {sent:X?}");
            sent.push(stage.exchange(&mut bus, &mut unit, &cmd).1.axes[0].state);
        }
        assert_eq!(stage.state, PowerState::SwitchOnDisabled);
        assert!(sent.iter().all(|s| *s != DriveState::Operational));
        bus.reset();
        bus.enable();
        let (_, fb, req) = stage.exchange(&mut bus, &mut unit, &cmd);
        assert_eq!(req.controlword, cw::DISABLE_VOLTAGE);
        assert_eq!(fb.axes[0].state, DriveState::Disabled);
    }

    #[test]
    fn shutdown_walk_sends_disable_operation_then_shutdown_then_disable_voltage() {
        let (mut bus, mut unit) = setup();
        bus.enable();
        let mut stage = Stage::new(0);
        let cmd = CycleCommand::default();
        stage.enable(&mut bus, &mut unit, &cmd);
        bus.shutdown();
        let mut words = Vec::new();
        while !bus.is_shut_down() {
            assert!(words.len() < 10, "no end: {words:X?}");
            words.push(stage.exchange(&mut bus, &mut unit, &cmd).2.controlword);
        }
        words.dedup();
        // The first request after `shutdown` still answers the enabled statusword read
        // before it: the walk starts there.
        assert_eq!(
            words,
            [cw::SWITCH_ON_CMD, cw::SHUTDOWN, cw::DISABLE_VOLTAGE],
            "{words:X?}"
        );
    }

    #[test]
    fn a_link_down_ends_the_shutdown_walk_at_once() {
        let (mut bus, mut unit) = setup();
        bus.enable();
        let mut stage = Stage::new(0);
        stage.enable(&mut bus, &mut unit, &CycleCommand::default());
        bus.shutdown();
        unit.hang_up(true);
        let mut fb = CycleFeedback::default();
        let _ = bus.cycle(&CycleCommand::default(), &mut fb);
        assert!(bus.is_shut_down());
    }
}
