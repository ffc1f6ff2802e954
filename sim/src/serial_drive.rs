//! A simulated multi-axis drive unit behind the serial protocol (`hal/SERIAL_PROTOCOL.md`):
//! one reply per request, CiA 402 drives per axis, optionally a spindle drive in velocity
//! mode (protocol version 2), a communication watchdog, and fault injection. No I/O: the `sim-serial` binary feeds it bytes from a pseudo-terminal.

use hal::MAX_AXES;
use hal::cia402::PowerState;
use hal::serial::frame::{self, Decoder};
use hal::serial::message::{AxisReply, Reply, Request};

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
}

impl SerialDriveUnit {
    pub fn new(drives: Vec<Cia402Drive>) -> SerialDriveUnit {
        assert!((1..=MAX_AXES).contains(&drives.len()));
        SerialDriveUnit {
            drives,
            spindle: None,
            inject: SerialInjection::default(),
            decoder: Decoder::default(),
            last_request_ms: None,
            exchanges: 0,
        }
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
            {
                continue; // misconfigured controller: no answer, it times out
            }
            let mut reply = Reply {
                seq: req.seq,
                axes: req.axes,
                axis: [AxisReply::default(); MAX_AXES],
                spindle: None,
            };
            for ((d, r), y) in self.drives.iter_mut().zip(&req.axis).zip(&mut reply.axis) {
                d.cycle(r.controlword, r.target_increments, 0.004);
                *y = AxisReply {
                    statusword: d.statusword(),
                    position_increments: d.position_increments(),
                    error_code: d.error_code(),
                };
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
            && now_ms.saturating_sub(last) > WATCHDOG_MS
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
