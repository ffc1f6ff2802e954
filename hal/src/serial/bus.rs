//! [`DriveBus`] over one serial port serving up to [`MAX_AXES`] axes of one drive unit.
//!
//! Each tick: read what arrived (the reply to the previous tick's request), advance each
//! axis's CiA 402 enable sequence, then write this tick's request. The port is non-blocking
//! (zero timeout), so a tick never waits for the drive; a reply missing for
//! `reply_timeout_ticks` consecutive ticks is a fault. A port that reports hang-up or an I/O
//! error is closed; [`DriveBus::reset`] opens it again (the operator's reset after replugging).
//!
//! With a spindle drive configured the link speaks protocol version 2: each request carries
//! the spindle's controlword and target velocity, each reply its statusword and actual
//! velocity. The spindle goes through the same CiA 402 enable sequence and fault handling as
//! the axes. Without one it speaks version 1, as drive units without a spindle expect.

use std::io::{self, Read, Write};
use std::time::Duration;

use serialport::TTYPort;

use super::frame::{self, Decoder, FrameError};
use super::message::{AxisRequest, Reply, Request};
use crate::cia402::{self, PowerState, cw, sw};
use crate::{
    AxisFeedback, BusFault, CycleCommand, CycleFeedback, DriveBus, DriveState, FaultReason,
    MAX_AXES,
};

#[derive(Clone, Debug, PartialEq)]
pub struct SerialAxis {
    /// Reported in alarms (the drive unit's axis address).
    pub node_id: u8,
    pub increments_per_mm: f64,
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
    /// Ticks allowed for the enable sequence.
    pub enable_timeout_ticks: u32,
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
        }
    }
}

#[derive(Clone, Copy, Debug, PartialEq)]
enum Phase {
    Idle,
    Enabling { since: u64 },
    Operational,
    Faulted(FaultReason),
}

#[derive(Clone, Copy)]
struct Axis {
    /// The spindle: the target is a velocity, holding still means speed 0.
    velocity: bool,
    phase: Phase,
    statusword: u16,
    position_increments: i32,
    error_code: u16,
    controlword: u16,
    target_increments: i32,
}

pub struct SerialBus {
    cfg: SerialConfig,
    port: Option<TTYPort>,
    decoder: Decoder,
    /// The axes (`[..n_axes]`), then the spindle if configured.
    axes: Vec<Axis>,
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
}

enum Ready {
    Nothing,
    Data,
    HungUp,
}

/// Whether the port has bytes (or an end-of-file) to read, without waiting.
fn readiness(port: &TTYPort) -> Ready {
    use std::os::fd::AsRawFd;
    let mut fd = libc::pollfd {
        fd: port.as_raw_fd(),
        events: libc::POLLIN,
        revents: 0,
    };
    // SAFETY: one valid pollfd, zero timeout.
    let n = unsafe { libc::poll(&mut fd, 1, 0) };
    if n < 0 {
        // EINTR: try again next tick.
        return Ready::Nothing;
    }
    if fd.revents & libc::POLLIN != 0 {
        Ready::Data
    } else if fd.revents & (libc::POLLHUP | libc::POLLERR | libc::POLLNVAL) != 0 {
        Ready::HungUp
    } else {
        Ready::Nothing
    }
}

fn open_port(cfg: &SerialConfig) -> Result<TTYPort, String> {
    serialport::new(&cfg.path, cfg.baud)
        .timeout(Duration::ZERO)
        .open_native()
        .map_err(|e| format!("cannot open serial port {}: {e}", cfg.path))
}

impl SerialBus {
    /// Opens the port. Nothing is sent before the first cycle.
    pub fn open(cfg: SerialConfig) -> Result<SerialBus, String> {
        if cfg.axes.is_empty() || cfg.axes.len() > MAX_AXES {
            return Err(format!(
                "{} axes on serial link {}, 1..={MAX_AXES} are supported",
                cfg.axes.len(),
                cfg.path
            ));
        }
        if let Some(i) = cfg
            .axes
            .iter()
            .position(|a| !(a.increments_per_mm.is_finite() && a.increments_per_mm > 0.0))
        {
            return Err(format!("increments per mm of axis {i} must be positive"));
        }
        if let Some(sp) = &cfg.spindle
            && !(sp.units_per_rpm.is_finite() && sp.units_per_rpm > 0.0)
        {
            return Err("velocity units per rpm of the spindle must be positive".into());
        }
        let port = open_port(&cfg)?;
        let axis = Axis {
            velocity: false,
            phase: Phase::Idle,
            statusword: 0,
            position_increments: 0,
            error_code: 0,
            controlword: 0,
            target_increments: 0,
        };
        let mut axes = vec![axis; cfg.axes.len()];
        if cfg.spindle.is_some() {
            axes.push(Axis {
                velocity: true,
                ..axis
            });
        }
        Ok(SerialBus {
            n_axes: cfg.axes.len(),
            axes,
            cfg,
            port: Some(port),
            decoder: Decoder::default(),
            tick: 0,
            seq: 0,
            awaiting: false,
            missing: 0,
            corrupt_since_reply: 0,
            have_feedback: false,
            link_fault: None,
            rx: [0; 256],
        })
    }

    fn link_down(&mut self) {
        self.port = None;
        self.link_fault = Some(FaultReason::LinkDown);
    }

    /// Reads everything waiting; applies the reply to the last request.
    fn receive(&mut self) {
        // Bounded: a babbling line cannot hold the tick.
        for _ in 0..8 {
            let Some(port) = self.port.as_mut() else {
                return;
            };
            // Poll first: serialport reports "nothing to read" as an allocated error, which
            // `cycle` must not cause every tick.
            match readiness(port) {
                Ready::Nothing => return,
                Ready::HungUp => {
                    self.link_down();
                    return;
                }
                Ready::Data => {}
            }
            let n = match port.read(&mut self.rx) {
                Ok(0) => {
                    // Readable but end of file: the other side hung up.
                    self.link_down();
                    return;
                }
                Ok(n) => n,
                Err(e)
                    if matches!(
                        e.kind(),
                        io::ErrorKind::TimedOut | io::ErrorKind::WouldBlock
                    ) =>
                {
                    return;
                }
                Err(e) if e.kind() == io::ErrorKind::Interrupted => continue,
                Err(_) => {
                    self.link_down();
                    return;
                }
            };
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
            // A reply must have our axes and, exactly when we have one, the spindle.
            let spindle = self.axes.len() > self.n_axes;
            if let Some(y) = reply
                && usize::from(y.axes) == self.n_axes
                && y.spindle.is_some() == spindle
            {
                let records = y.axis[..self.n_axes].iter().chain(y.spindle.as_ref());
                for (a, r) in self.axes.iter_mut().zip(records) {
                    a.statusword = r.statusword;
                    a.position_increments = r.position_increments;
                    a.error_code = r.error_code;
                }
                self.awaiting = false;
                self.missing = 0;
                self.corrupt_since_reply = 0;
                self.have_feedback = true;
            }
        }
    }

    fn update_axis(&mut self, i: usize, target: i32, fresh: bool) {
        let tick = self.tick;
        let limit = u64::from(self.cfg.enable_timeout_ticks);
        let a = &mut self.axes[i];
        let state = PowerState::from_statusword(a.statusword);
        match a.phase {
            Phase::Idle => {
                a.controlword = cw::DISABLE_VOLTAGE;
                a.target_increments = a.hold_target();
            }
            Phase::Enabling { since } => {
                a.target_increments = a.hold_target();
                if !fresh {
                    // Wait for a reply before stepping the state machine.
                } else if state == PowerState::OperationEnabled {
                    a.phase = Phase::Operational;
                    a.controlword = cw::ENABLE_OPERATION_CMD;
                } else if tick - since > limit {
                    a.phase = Phase::Faulted(FaultReason::EnableTimeout {
                        statusword: a.statusword,
                    });
                } else {
                    a.controlword = cia402::controlword_toward_enabled(state, a.controlword);
                }
            }
            Phase::Operational => {
                let s = a.statusword;
                if s & sw::FOLLOWING_ERROR != 0 {
                    a.phase = Phase::Faulted(FaultReason::FollowingError);
                } else if matches!(state, PowerState::Fault | PowerState::FaultReactionActive) {
                    a.phase = Phase::Faulted(FaultReason::DriveFault { code: a.error_code });
                } else if state != PowerState::OperationEnabled {
                    a.phase = Phase::Faulted(FaultReason::DriveDisabled { statusword: s });
                } else {
                    a.target_increments = target;
                }
            }
            Phase::Faulted(_) => {}
        }
        if matches!(a.phase, Phase::Faulted(_)) {
            a.controlword = cw::DISABLE_VOLTAGE;
            a.target_increments = a.hold_target();
        }
    }

    fn send_request(&mut self) {
        let Some(port) = self.port.as_mut() else {
            return;
        };
        self.seq = self.seq.wrapping_add(1);
        let record = |a: &Axis| AxisRequest {
            controlword: a.controlword,
            target_increments: a.target_increments,
        };
        let mut req = Request {
            seq: self.seq,
            axes: self.n_axes as u8,
            axis: [AxisRequest::default(); MAX_AXES],
            spindle: self.axes.get(self.n_axes).map(record),
        };
        for (r, a) in req.axis.iter_mut().zip(&self.axes[..self.n_axes]) {
            *r = record(a);
        }
        let mut payload = [0u8; 64];
        let n = req.encode(&mut payload);
        let mut out = [0u8; frame::MAX_FRAME];
        let len = frame::encode(&payload[..n], &mut out);
        // A frame is far smaller than any tty buffer; a short write means the line is stuck.
        match port.write(&out[..len]) {
            Ok(w) if w == len => self.awaiting = true,
            Ok(_) => self.awaiting = true,
            Err(e)
                if matches!(
                    e.kind(),
                    io::ErrorKind::TimedOut | io::ErrorKind::WouldBlock
                ) =>
            {
                self.awaiting = true
            }
            Err(_) => self.link_down(),
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
}

impl Axis {
    /// The target that holds the drive still: where it is, or speed 0 for the spindle.
    fn hold_target(&self) -> i32 {
        if self.velocity {
            0
        } else {
            self.position_increments
        }
    }
}

impl DriveBus for SerialBus {
    fn name(&self) -> &str {
        &self.cfg.path
    }

    fn axes(&self) -> usize {
        self.n_axes
    }

    fn has_spindle(&self) -> bool {
        self.axes.len() > self.n_axes
    }

    fn cycle(&mut self, cmd: &CycleCommand, feedback: &mut CycleFeedback) -> Result<(), BusFault> {
        self.tick += 1;
        let was_awaiting = self.awaiting;
        self.receive();
        let fresh = was_awaiting && !self.awaiting;
        if self.awaiting {
            self.missing += 1;
            if self.missing > self.cfg.reply_timeout_ticks && self.link_fault.is_none() {
                self.link_fault = Some(if self.corrupt_since_reply > 0 {
                    FaultReason::CorruptFrames
                } else {
                    FaultReason::Timeout
                });
            }
        }
        for i in 0..self.axes.len() {
            let units = match self.cfg.axes.get(i) {
                Some(c) => cmd.positions_mm[i] * c.increments_per_mm,
                None => {
                    // The spindle; a setpoint that is not a number stops it.
                    let rpm = if cmd.spindle_rpm.is_finite() {
                        cmd.spindle_rpm
                    } else {
                        0.0
                    };
                    rpm * self.spindle_units_per_rpm()
                }
            };
            let target = units
                .round()
                .clamp(f64::from(i32::MIN), f64::from(i32::MAX)) as i32;
            if self.link_fault.is_some() && !matches!(self.axes[i].phase, Phase::Idle) {
                // The drive is unreachable or unreliable: hold, and ask it to switch off.
                let a = &mut self.axes[i];
                a.controlword = cw::DISABLE_VOLTAGE;
                a.target_increments = a.hold_target();
            } else {
                self.update_axis(i, target, fresh);
            }
        }
        self.send_request();

        let state_of = |a: &Axis| match a.phase {
            _ if self.link_fault.is_some() => DriveState::Fault,
            Phase::Idle => DriveState::Disabled,
            Phase::Enabling { .. } => DriveState::Enabling,
            Phase::Operational => DriveState::Operational,
            Phase::Faulted(_) => DriveState::Fault,
        };
        for ((fb, a), c) in feedback.axes.iter_mut().zip(&self.axes).zip(&self.cfg.axes) {
            *fb = AxisFeedback {
                position_mm: f64::from(a.position_increments) / c.increments_per_mm,
                state: state_of(a),
            };
        }
        (feedback.spindle_rpm, feedback.spindle_state) = match self.axes.get(self.n_axes) {
            Some(a) => {
                let state = state_of(a);
                let rpm = if state == DriveState::Operational {
                    f64::from(a.position_increments) / self.spindle_units_per_rpm()
                } else {
                    0.0
                };
                (rpm, state)
            }
            None => (0.0, DriveState::Disabled),
        };
        if let Some(reason) = self.link_fault {
            let (axis, node) = self.link_scope();
            return Err(BusFault { axis, node, reason });
        }
        for (i, a) in self.axes.iter().enumerate() {
            if let Phase::Faulted(reason) = a.phase {
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

    fn enable(&mut self) {
        let tick = self.tick;
        for a in &mut self.axes {
            if a.phase == Phase::Idle {
                a.phase = Phase::Enabling { since: tick };
            }
        }
    }

    fn reset(&mut self) {
        if self.port.is_none() {
            // Reopening allocates and may take a moment; it happens only on the operator's
            // reset, never in `cycle`. If the port is still missing the fault stays.
            match open_port(&self.cfg) {
                Ok(p) => self.port = Some(p),
                Err(_) => return,
            }
        }
        self.decoder.clear();
        self.link_fault = None;
        self.awaiting = false;
        self.missing = 0;
        self.corrupt_since_reply = 0;
        let tick = self.tick;
        // Every axis goes through the enable sequence again: a drive that lost its link has
        // switched itself off, one that did not is confirmed enabled on the first reply.
        for a in &mut self.axes {
            a.phase = Phase::Enabling { since: tick };
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::serial::message::AxisReply;
    use serialport::SerialPort;

    /// The test plays the drive on the master side of a pty pair: it answers requests by
    /// hand with the statusword it is given.
    struct Drive {
        port: TTYPort,
        decoder: Decoder,
    }

    impl Drive {
        fn answer(&mut self, statusword: u16, position: i32) -> Option<Request> {
            let mut buf = [0u8; 256];
            let mut got = None;
            std::thread::sleep(Duration::from_millis(5));
            if let Ok(n) = self.port.read(&mut buf) {
                self.decoder.feed(&buf[..n], |r| {
                    if let Ok(p) = r {
                        got = Request::decode(p);
                    }
                });
            }
            let req = got?;
            let mut y = Reply {
                seq: req.seq,
                axes: 1,
                axis: [AxisReply::default(); MAX_AXES],
                spindle: None,
            };
            y.axis[0] = AxisReply {
                statusword,
                position_increments: position,
                error_code: 0,
            };
            let mut p = [0u8; 64];
            let n = y.encode(&mut p);
            let mut f = [0u8; frame::MAX_FRAME];
            let len = frame::encode(&p[..n], &mut f);
            self.port.write_all(&f[..len]).unwrap();
            Some(req)
        }
    }

    fn setup() -> (SerialBus, Drive) {
        let (mut master, slave) = TTYPort::pair().unwrap();
        master.set_timeout(Duration::from_millis(50)).unwrap();
        let path = slave.name().unwrap();
        let bus = SerialBus::open(SerialConfig::new(
            &path,
            vec![SerialAxis {
                node_id: 4,
                increments_per_mm: 100.0,
            }],
        ))
        .unwrap();
        // Keep the slave fd open in the test so the pty stays alive.
        std::mem::forget(slave);
        (
            bus,
            Drive {
                port: master,
                decoder: Decoder::default(),
            },
        )
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
        let (mut bus, drive) = setup();
        bus.enable();
        drop(drive); // closes the pty master: the line hangs up
        let mut fb = CycleFeedback::default();
        let cmd = CycleCommand::default();
        let mut last = Ok(());
        for _ in 0..3 {
            last = bus.cycle(&cmd, &mut fb);
        }
        assert_eq!(last.unwrap_err().reason, FaultReason::LinkDown);
        assert_eq!(fb.axes[0].state, DriveState::Fault);
    }
}
