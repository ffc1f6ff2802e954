//! A simulated multi-axis drive unit behind the serial protocol (`hal/SERIAL_PROTOCOL.md`):
//! one reply per request, CiA 402 drives per axis, optionally a spindle drive in velocity
//! mode (protocol version 2), home switches and the reference command (protocol version 3), a
//! 64-bit input and output word with a safe output word (protocol version 4), a
//! communication watchdog, and fault injection. No I/O of its own: the `sim-serial` binary
//! feeds it bytes from a pseudo-terminal.

use std::sync::Arc;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};

use hal::MAX_AXES;
use hal::cia402::PowerState;
use hal::serial::frame::{self, Decoder};
use hal::serial::message::{
    AxisReply, HomeAction, HomeCommand, HomeResult, HomeStatus, IoCommand, IoStatus, Reply, Request,
};

use crate::cia402_drive::{COMMUNICATION_LOST, Cia402Drive};

/// Without a request for this long, an enabled drive faults (error code 8130h) and the
/// outputs fall to the safe output word: 25 ticks of 4 ms, the controller's default
/// `reply_timeout_ticks`, so both ends give the link up at about the same time.
pub const WATCHDOG_MS: u64 = 100;

/// The unit's digital I/O words, shared: a test (or the binary's stdin) sets the inputs and
/// reads the outputs while the unit runs elsewhere. Clones are handles to the same words.
#[derive(Clone, Debug, Default)]
pub struct IoWords {
    inputs: Arc<AtomicU64>,
    outputs: Arc<AtomicU64>,
    /// The word the outputs fall to on link loss: 0 (all off) until a controller sends one.
    safe: Arc<AtomicU64>,
    /// The watchdog set the outputs to the safe word; the next valid request clears it.
    fallen: Arc<AtomicBool>,
}

impl IoWords {
    /// The input word (bit i: the unit's input i).
    pub fn inputs(&self) -> u64 {
        self.inputs.load(Ordering::Relaxed)
    }

    pub fn set_inputs(&self, word: u64) {
        self.inputs.store(word, Ordering::Relaxed);
    }

    /// Sets input `bit` (0..=63; others are ignored).
    pub fn set_input(&self, bit: u8, on: bool) {
        let Some(mask) = 1u64.checked_shl(u32::from(bit)) else {
            return;
        };
        if on {
            self.inputs.fetch_or(mask, Ordering::Relaxed);
        } else {
            self.inputs.fetch_and(!mask, Ordering::Relaxed);
        }
    }

    /// The output word as the unit drives it.
    pub fn outputs(&self) -> u64 {
        self.outputs.load(Ordering::Relaxed)
    }

    /// The safe output word the unit holds.
    pub fn safe_outputs(&self) -> u64 {
        self.safe.load(Ordering::Relaxed)
    }

    /// Whether the watchdog set the outputs to the safe word (no request since).
    pub fn is_fallen(&self) -> bool {
        self.fallen.load(Ordering::Relaxed)
    }

    /// A valid version 4 request: its outputs, and its safe word if it carries one.
    fn apply(&self, c: IoCommand) {
        if let Some(safe) = c.safe_outputs {
            self.safe.store(safe, Ordering::Relaxed);
        }
        self.outputs.store(c.outputs, Ordering::Relaxed);
        self.fallen.store(false, Ordering::Relaxed);
    }

    /// The watchdog: the outputs take the safe word.
    fn fall_to_safe(&self) {
        self.outputs.store(self.safe_outputs(), Ordering::Relaxed);
        self.fallen.store(true, Ordering::Relaxed);
    }
}

#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct SerialInjection {
    /// Read requests but never answer.
    pub silent: bool,
    /// Flip one bit in every reply (the controller's CRC check must catch it).
    pub corrupt: bool,
}

pub struct SerialDriveUnit {
    pub drives: Vec<Cia402Drive>,
    /// The spindle drive (velocity mode), answered in version 2 requests.
    pub spindle: Option<Cia402Drive>,
    pub inject: SerialInjection,
    decoder: Decoder,
    last_request_ms: Option<u64>,
    /// Requests answered so far.
    pub exchanges: u64,
    /// Newest protocol version the unit speaks (4; 1 to 3 plays an old unit, which does not
    /// answer newer requests).
    pub max_version: u8,
    /// The input and output words (version 4); clone it for a handle.
    pub io: IoWords,
    /// A controller sent a safe output word since power-on (the reply's flags bit 2).
    safe_held: bool,
    /// Home switch per axis: (where it is in the drive's power-on coordinates, mm; the side it
    /// is pressed on: -1 at and below, +1 at and above).
    pub switches: Vec<Option<(f64, f64)>>,
    /// Shift of each axis's reported position by reference commands, increments.
    shifts: Vec<i64>,
    /// The last reference command handled and its result.
    home_id: u8,
    home_result: HomeResult,
    /// Communication watchdog, ms (default [`WATCHDOG_MS`]).
    pub watchdog_ms: u64,
}

impl SerialDriveUnit {
    pub fn new(drives: Vec<Cia402Drive>) -> SerialDriveUnit {
        assert!((1..=MAX_AXES).contains(&drives.len()));
        SerialDriveUnit {
            spindle: None,
            inject: SerialInjection::default(),
            decoder: Decoder::default(),
            last_request_ms: None,
            exchanges: 0,
            max_version: 4,
            io: IoWords::default(),
            safe_held: false,
            switches: vec![None; drives.len()],
            shifts: vec![0; drives.len()],
            home_id: 0,
            home_result: HomeResult::Applied,
            watchdog_ms: WATCHDOG_MS,
            drives,
        }
    }

    /// Home switch of `axis` at `at_mm` (power-on coordinates), pressed on side `side`.
    pub fn with_home_switch(mut self, axis: usize, at_mm: f64, side: f64) -> Self {
        self.switches[axis] = Some((at_mm, side.signum()));
        self
    }

    /// The home switch inputs: bit i for axis i.
    fn switch_bits(&self) -> u8 {
        let pressed = |(d, s): (&Cia402Drive, &Option<(f64, f64)>)| {
            s.is_some_and(|(at, side)| (d.position_mm() - at) * side >= 0.0)
        };
        self.drives
            .iter()
            .zip(&self.switches)
            .enumerate()
            .filter(|&(_, ds)| pressed(ds))
            .fold(0, |bits, (i, _)| bits | 1 << i)
    }

    /// A reference command, applied once per id before the request's targets: the axis's
    /// positions (actual and target) shift together, so the drive does not move.
    fn reference_command(&mut self, h: HomeCommand) {
        if h.action != HomeAction::SetReference || h.id == self.home_id {
            return;
        }
        self.home_id = h.id;
        self.home_result = match self.shifts.get_mut(usize::from(h.axis)) {
            Some(s) => {
                *s += i64::from(h.shift_increments);
                HomeResult::Applied
            }
            None => HomeResult::Refused,
        };
    }

    /// A new line (replugged): forget any partial frame.
    pub fn reconnect(&mut self) {
        self.decoder.clear();
    }

    /// Handles received bytes; appends the replies to `out`.
    pub fn on_bytes(&mut self, bytes: &[u8], now_ms: u64, out: &mut Vec<u8>) {
        let mut requests = [None; 8];
        let mut count = 0;
        self.decoder.feed(bytes, |r| {
            if let Ok(p) = r
                && let Some(req) = Request::decode(p)
                && count < requests.len()
            {
                requests[count] = Some(req);
                count += 1;
            }
        });
        for req in requests.iter().flatten() {
            self.last_request_ms = Some(now_ms);
            if let Some(reply) = self.answer(req)
                && !self.inject.silent
            {
                self.send(&reply, out);
            }
        }
    }

    /// Applies one request and makes its reply; `None` for a request this unit cannot take
    /// (a misconfigured controller, or a version it does not know).
    fn answer(&mut self, req: &Request) -> Option<Reply> {
        if usize::from(req.axes) != self.drives.len()
            || (req.spindle.is_some() && self.spindle.is_none())
            || req.version() > self.max_version
        {
            return None;
        }
        if let Some(h) = req.home {
            self.reference_command(h);
        }
        let mut reply = Reply {
            seq: req.seq,
            axes: req.axes,
            axis: [AxisReply::default(); MAX_AXES],
            spindle: None,
            home: None,
            io: None,
        };
        let drives = self.drives.iter_mut().zip(&self.shifts);
        for ((d, &shift), (r, y)) in drives.zip(req.axis.iter().zip(&mut reply.axis)) {
            let to_i32 = |v: i64| v.clamp(i64::from(i32::MIN), i64::from(i32::MAX)) as i32;
            d.cycle(
                r.controlword,
                to_i32(i64::from(r.target_increments) - shift),
                0.004,
            );
            *y = AxisReply {
                statusword: d.statusword(),
                position_increments: to_i32(i64::from(d.position_increments()) + shift),
                error_code: d.error_code(),
            };
        }
        // Version 3 (and 4 when flagged): switches after this cycle's motion, and the
        // acknowledgement.
        if req.home.is_some() {
            reply.home = Some(HomeStatus {
                switches: self.switch_bits(),
                id: self.home_id,
                result: self.home_result,
            });
        }
        // Version 2: the spindle record. A version 1 request leaves the spindle alone and
        // gets a version 1 reply.
        if let (Some(r), Some(d)) = (req.spindle, self.spindle.as_mut()) {
            d.cycle_velocity(r.controlword, r.target_increments, 0.004);
            reply.spindle = Some(AxisReply {
                statusword: d.statusword(),
                position_increments: d.velocity_units(),
                error_code: d.error_code(),
            });
        }
        // Version 4: outputs (and the safe word) taken, the inputs reported.
        if let Some(c) = req.io {
            self.io.apply(c);
            self.safe_held |= c.safe_outputs.is_some();
            reply.io = Some(IoStatus {
                inputs: self.io.inputs(),
                safe_held: self.safe_held,
            });
        }
        Some(reply)
    }

    /// Frames `reply` into `out` (with a flipped bit under the `corrupt` injection).
    fn send(&mut self, reply: &Reply, out: &mut Vec<u8>) {
        let mut p = [0u8; frame::MAX_PAYLOAD];
        let n = reply.encode(&mut p);
        let mut f = [0u8; frame::MAX_FRAME];
        let len = frame::encode(&p[..n], &mut f);
        if self.inject.corrupt {
            f[len / 2] ^= 0x10;
            if f[len / 2] == 0 {
                f[len / 2] = 0x10;
            }
        }
        out.extend_from_slice(&f[..len]);
        self.exchanges += 1;
    }

    /// Communication watchdog: no request for `watchdog_ms` faults the enabled drives and
    /// sets the outputs to the safe output word.
    pub fn poll(&mut self, now_ms: u64) {
        if let Some(last) = self.last_request_ms
            && now_ms.saturating_sub(last) > self.watchdog_ms
        {
            self.last_request_ms = None;
            self.io.fall_to_safe();
            for d in self.drives.iter_mut().chain(self.spindle.as_mut()) {
                if d.state() == PowerState::OperationEnabled {
                    d.fault(COMMUNICATION_LOST);
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::drive::SimDriveParams;
    use hal::cia402::cw;
    use hal::serial::message::AxisRequest;

    fn exchange(unit: &mut SerialDriveUnit, req: &Request) -> Option<Reply> {
        let mut p = [0u8; frame::MAX_PAYLOAD];
        let n = req.encode(&mut p);
        let mut f = [0u8; frame::MAX_FRAME];
        let len = frame::encode(&p[..n], &mut f);
        let mut out = Vec::new();
        unit.on_bytes(&f[..len], 0, &mut out);
        let mut reply = None;
        Decoder::default().feed(&out, |r| reply = r.ok().and_then(Reply::decode));
        reply
    }

    fn request(seq: u8, target: i32, home: Option<HomeCommand>) -> Request {
        let mut axis = [AxisRequest::default(); MAX_AXES];
        axis[0] = AxisRequest {
            controlword: cw::ENABLE_OPERATION_CMD,
            target_increments: target,
        };
        Request {
            seq,
            axes: 1,
            axis,
            spindle: None,
            home,
            io: None,
        }
    }

    #[test]
    fn switch_and_reference_command_once_per_id() {
        let drive = Cia402Drive::new(SimDriveParams::default(), 100.0, 0.0);
        let mut unit = SerialDriveUnit::new(vec![drive]).with_home_switch(0, -1.0, -1.0);
        let none = Some(HomeCommand::default());
        let y = exchange(&mut unit, &request(1, 0, none)).unwrap();
        assert_eq!(y.home.unwrap().switches, 0);
        // Drive it onto the switch (at -1 mm and below).
        unit.drives[0] = Cia402Drive::new(SimDriveParams::default(), 100.0, -1.2);
        let y = exchange(&mut unit, &request(2, -120, none)).unwrap();
        assert_eq!(y.home.unwrap().switches, 1);
        let cmd = HomeCommand {
            action: HomeAction::SetReference,
            id: 1,
            axis: 0,
            shift_increments: 120,
        };
        // The target comes in the new reference (0 = where it stands): no motion.
        for seq in 3..6 {
            let y = exchange(&mut unit, &request(seq, 0, Some(cmd))).unwrap();
            assert_eq!(y.axis[0].position_increments, 0, "applied once");
            assert_eq!(y.home.unwrap().id, 1);
            assert_eq!(y.home.unwrap().result, HomeResult::Applied);
        }
        assert!((unit.drives[0].position_mm() + 1.2).abs() < 1e-9);
        let bad = Some(HomeCommand {
            id: 2,
            axis: 4,
            ..cmd
        });
        let y = exchange(&mut unit, &request(6, 0, bad)).unwrap();
        assert_eq!(y.home.unwrap().result, HomeResult::Refused);
        // A unit of version 2 does not answer version 3.
        unit.max_version = 2;
        assert_eq!(exchange(&mut unit, &request(7, 0, none)), None);
        assert!(exchange(&mut unit, &request(8, 0, None)).is_some());
    }

    /// Version 4: the outputs reach the word, the inputs come back, the safe word is held
    /// and the watchdog falls to it; a unit of version 3 does not answer.
    #[test]
    fn io_words_safe_word_and_watchdog() {
        let drive = Cia402Drive::new(SimDriveParams::default(), 100.0, 0.0);
        let mut unit = SerialDriveUnit::new(vec![drive]);
        let io = unit.io.clone();
        io.set_inputs(0b1001);
        io.set_input(63, true);
        io.set_input(64, true);
        let mut req = request(1, 0, None);
        req.io = Some(IoCommand {
            outputs: 0b110,
            safe_outputs: Some(0b001),
        });
        let y = exchange(&mut unit, &req).unwrap();
        let status = y.io.unwrap();
        assert_eq!((status.inputs, status.safe_held), (1 << 63 | 0b1001, true));
        assert_eq!((io.outputs(), io.safe_outputs()), (0b110, 0b001));
        req.io = Some(IoCommand {
            outputs: 0b100,
            safe_outputs: None,
        });
        assert!(exchange(&mut unit, &req).unwrap().io.unwrap().safe_held);
        assert_eq!(io.outputs(), 0b100);
        unit.poll(WATCHDOG_MS);
        assert!(!io.is_fallen(), "not yet");
        unit.poll(WATCHDOG_MS + 1);
        assert!(io.is_fallen());
        assert_eq!(io.outputs(), 0b001);
        exchange(&mut unit, &req).unwrap();
        assert_eq!((io.outputs(), io.is_fallen()), (0b100, false));
        unit.max_version = 3;
        assert_eq!(exchange(&mut unit, &req), None);
    }
}
