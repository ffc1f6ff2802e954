//! A simulated multi-axis drive unit behind the serial protocol (`hal/SERIAL_PROTOCOL.md`):
//! one reply per request, CiA 402 drives per axis, optionally a spindle drive in velocity
//! mode (protocol version 2), home switches and the reference command (protocol version 3), a
//! communication watchdog, and fault injection. No I/O: the `sim-serial` binary feeds it bytes
//! from a pseudo-terminal.

use hal::MAX_AXES;
use hal::cia402::PowerState;
use hal::serial::frame::{self, Decoder};
use hal::serial::message::{
    AxisReply, HomeAction, HomeCommand, HomeResult, HomeStatus, Reply, Request,
};

use crate::cia402_drive::{COMMUNICATION_LOST, Cia402Drive};

/// Without a request for this long, an enabled drive faults (error code 8130h).
pub const WATCHDOG_MS: u64 = 100;

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
    /// Newest protocol version the unit speaks (3; 1 or 2 plays an old unit, which does not
    /// answer newer requests).
    pub max_version: u8,
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
            max_version: 3,
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
            if usize::from(req.axes) != self.drives.len()
                || (req.spindle.is_some() && self.spindle.is_none())
                || req.version() > self.max_version
            {
                continue; // misconfigured controller, or a version this unit does not know
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
            // Version 3: switches after this cycle's motion, and the acknowledgement.
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
            if self.inject.silent {
                continue;
            }
            let mut p = [0u8; 64];
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
    }

    /// Communication watchdog.
    pub fn poll(&mut self, now_ms: u64) {
        if let Some(last) = self.last_request_ms
            && now_ms.saturating_sub(last) > self.watchdog_ms
        {
            self.last_request_ms = None;
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
        let mut p = [0u8; 64];
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
}
