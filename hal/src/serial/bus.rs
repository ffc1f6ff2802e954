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
//!
//! With digital I/O wired to the unit ([`IoPoint::Serial`](crate::io::IoPoint) in
//! `SerialConfig::io`) it speaks version 4: each request carries the unit's output word, each
//! reply its input word, and the safe output word goes out until the unit confirms it
//! ([`UnitIo`]). Older units are refused the same way ([`VersionCheck`]).

use std::time::Duration;

use super::SerialError;
use super::frame::{self, Decoder, FrameError};
use super::message::{
    AxisRequest, HomeAction, HomeCommand, HomeResult, HomeStatus, Reply, Request,
};
use super::port::{LinkDown, SerialPort, TtyPort};
use super::unit_io::{self, UnitIo};
use super::version::VersionCheck;
pub use super::version::{PROBE_ANSWERS, PROBE_EVERY_TICKS};
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
    /// Digital I/O of the unit (`IoPoint::Serial`; docs/io.md); other points are not this
    /// bus's.
    pub io: crate::io::IoMap,
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
            io: crate::io::IoMap::default(),
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
    /// The version the link needs and the probes that find an old unit.
    version: VersionCheck,
    /// The unit's digital I/O (version 4).
    io: UnitIo,
    shutting_down: bool,
}

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
    /// Some reply carried the homing record (the drive's last id is known).
    status_seen: bool,
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
    // The hand-over's largest step is one tick at this speed.
    if let Some(axis) = cfg
        .axes
        .iter()
        .position(|a| !(a.max_velocity_mm_s.is_finite() && a.max_velocity_mm_s > 0.0))
    {
        return Err(SerialError::AxisSpeed { axis });
    }
    if let Some(sp) = &cfg.spindle
        && !(sp.units_per_rpm.is_finite() && sp.units_per_rpm > 0.0)
    {
        return Err(SerialError::SpindleScale);
    }
    if let Some(bit) = unit_io::bad_bit(&cfg.io) {
        return Err(SerialError::IoBit { bit });
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
        let io = UnitIo::new(&cfg.io);
        SerialBus {
            version: VersionCheck::new(cfg.spindle.is_some(), cfg.homing, io.is_used()),
            io,
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
    /// when it has our axes and, exactly when we have them, the spindle, homing and I/O.
    fn on_reply(&mut self, y: &Reply) {
        let spindle = self.axes.len() > self.n_axes;
        if self.version.is_older(y.version()) {
            self.probe_answered(y);
        } else if usize::from(y.axes) == self.n_axes
            && y.spindle.is_some() == spindle
            && y.home.is_some() == self.cfg.homing
            && y.io.is_some() == self.io.is_used()
        {
            self.version.confirm();
            let records = y.axis[..self.n_axes].iter().chain(y.spindle.as_ref());
            for (d, r) in self.axes.iter_mut().zip(records) {
                d.on_status(r.statusword, r.position_increments);
                d.set_error_code(r.error_code);
            }
            if let Some(h) = y.home {
                self.home_status(h);
            }
            if let Some(s) = y.io {
                self.io.on_status(s);
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

    /// Writes this tick's request (`outputs`: the configuration's output bits).
    fn send_request(&mut self, outputs: crate::io::IoBits) {
        if !self.port_open {
            return;
        }
        self.seq = self.seq.wrapping_add(1);
        let record = |d: &Drive| AxisRequest {
            controlword: d.controlword(),
            target_increments: d.target_increments(),
        };
        let probe = self.version.next_request(self.missing);
        // A probe of version 3 carries the homing record; older ones carry neither it nor I/O.
        let home = self.cfg.homing && probe.is_none_or(|v| v >= 3);
        let io = self.io.is_used() && probe.is_none();
        let mut req = Request {
            seq: self.seq,
            axes: self.n_axes as u8,
            axis: [AxisRequest::default(); MAX_AXES],
            spindle: self.axes.get(self.n_axes).map(record),
            home: home.then(|| self.home_command()),
            io: io.then(|| self.io.command(outputs)),
        };
        for (r, a) in req.axis.iter_mut().zip(&self.axes[..self.n_axes]) {
            *r = record(a);
        }
        if probe.is_some() {
            // The probe must not switch anything on in a unit we are about to refuse.
            for r in req.axis.iter_mut().chain(req.spindle.as_mut()) {
                r.controlword = cw::DISABLE_VOLTAGE;
            }
        }
        let mut payload = [0u8; frame::MAX_PAYLOAD];
        let n = req.encode(&mut payload);
        let mut out = [0u8; frame::MAX_FRAME];
        let len = frame::encode(&payload[..n], &mut out);
        match self.port.write(&out[..len]) {
            Ok(()) => self.awaiting = true,
            Err(LinkDown) => self.link_down(),
        }
    }

    /// An older-version reply than the link needs: the answer to a probe. A unit that
    /// answers probes but never the needed version is an old unit: refused, clearly.
    fn probe_answered(&mut self, y: &Reply) {
        if !self.version.probing() {
            return;
        }
        self.awaiting = false;
        self.missing = 0;
        self.corrupt_since_reply = 0;
        if let Some(refusal) = self.version.probe_answered(y.version()) {
            self.link_fault = Some(refusal);
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
        let first = !self.homing.status_seen;
        self.homing.status_seen = true;
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
        feedback.inputs = self.io.inputs();
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
        self.send_request(cmd.outputs);
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
        // The unit may have been swapped: find out its version again, and send it the safe
        // output word. A reference command still pending is dropped (its axis is no longer
        // homed: the fault cleared that).
        self.homing = Homing {
            acked_id: self.homing.acked_id,
            ..Homing::default()
        };
        self.version.restart();
        self.io.forget_unit();
        let tick = self.tick;
        // Every axis goes through the enable sequence again: a drive that lost its link has
        // switched itself off, one that did not is confirmed enabled on the first reply.
        for d in &mut self.axes {
            d.begin_enable(tick);
        }
    }
}

#[cfg(test)]
#[path = "bus_tests.rs"]
mod tests;
