//! The two messages of the serial drive protocol (see `hal/SERIAL_PROTOCOL.md`): the
//! controller's request (controlword and target per axis) and the drive's reply (statusword,
//! actual position and error code per axis). Little endian, fixed layout.
//!
//! Version 1 (types 01h/81h) has axes only. Version 2 (types 02h/82h) appends one record for
//! the spindle drive: its controlword and target velocity, and its statusword, actual
//! velocity and error code. The controller speaks version 2 only when a spindle is configured,
//! so drive units of version 1 keep working unchanged.

use crate::MAX_AXES;

/// Version 1 request (axes only).
pub const REQUEST: u8 = 0x01;
/// Version 1 reply.
pub const REPLY: u8 = 0x81;
/// Version 2 request: axes, then the spindle.
pub const REQUEST_V2: u8 = 0x02;
/// Version 2 reply: axes, then the spindle.
pub const REPLY_V2: u8 = 0x82;
const HEADER: usize = 3;
const REQUEST_AXIS: usize = 6;
const REPLY_AXIS: usize = 8;

#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct AxisRequest {
    /// CiA 402 controlword.
    pub controlword: u16,
    /// Target position, increments; for the spindle the target velocity, drive units.
    pub target_increments: i32,
}

#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct AxisReply {
    /// CiA 402 statusword.
    pub statusword: u16,
    /// Actual position, increments; for the spindle the actual velocity, drive units.
    pub position_increments: i32,
    /// CiA 402 error code (0x603F), 0 when none.
    pub error_code: u16,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Request {
    pub seq: u8,
    pub axes: u8,
    pub axis: [AxisRequest; MAX_AXES],
    /// The spindle record: present in version 2 only.
    pub spindle: Option<AxisRequest>,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Reply {
    /// Echo of the request's sequence number.
    pub seq: u8,
    pub axes: u8,
    pub axis: [AxisReply; MAX_AXES],
    /// The spindle record: present in version 2 only.
    pub spindle: Option<AxisReply>,
}

/// Sequence number, axis count and whether a spindle record follows (version 2), if `p` is a
/// message of type `v1` or `v2` of exactly the right length.
fn header(p: &[u8], v1: u8, v2: u8, per_axis: usize) -> Option<(u8, u8, bool)> {
    let (&k, rest) = p.split_first()?;
    let (&seq, rest) = rest.split_first()?;
    let (&axes, rest) = rest.split_first()?;
    let spindle = match k {
        _ if k == v1 => false,
        _ if k == v2 => true,
        _ => return None,
    };
    let records = usize::from(axes) + usize::from(spindle);
    ((1..=MAX_AXES as u8).contains(&axes) && rest.len() == per_axis * records)
        .then_some((seq, axes, spindle))
}

fn put_request(out: &mut [u8], a: &AxisRequest) {
    out[..2].copy_from_slice(&a.controlword.to_le_bytes());
    out[2..6].copy_from_slice(&a.target_increments.to_le_bytes());
}

fn get_request(b: &[u8]) -> AxisRequest {
    AxisRequest {
        controlword: u16::from_le_bytes([b[0], b[1]]),
        target_increments: i32::from_le_bytes([b[2], b[3], b[4], b[5]]),
    }
}

fn put_reply(out: &mut [u8], a: &AxisReply) {
    out[..2].copy_from_slice(&a.statusword.to_le_bytes());
    out[2..6].copy_from_slice(&a.position_increments.to_le_bytes());
    out[6..8].copy_from_slice(&a.error_code.to_le_bytes());
}

fn get_reply(b: &[u8]) -> AxisReply {
    AxisReply {
        statusword: u16::from_le_bytes([b[0], b[1]]),
        position_increments: i32::from_le_bytes([b[2], b[3], b[4], b[5]]),
        error_code: u16::from_le_bytes([b[6], b[7]]),
    }
}

impl Request {
    /// Writes the payload into `out`; returns its length.
    pub fn encode(&self, out: &mut [u8; 64]) -> usize {
        let n = usize::from(self.axes.min(MAX_AXES as u8));
        let kind = if self.spindle.is_some() {
            REQUEST_V2
        } else {
            REQUEST
        };
        out[..HEADER].copy_from_slice(&[kind, self.seq, n as u8]);
        for (i, a) in self.axis[..n].iter().enumerate() {
            put_request(&mut out[HEADER + i * REQUEST_AXIS..], a);
        }
        let mut len = HEADER + n * REQUEST_AXIS;
        if let Some(s) = &self.spindle {
            put_request(&mut out[len..], s);
            len += REQUEST_AXIS;
        }
        len
    }

    pub fn decode(p: &[u8]) -> Option<Request> {
        let (seq, axes, spindle) = header(p, REQUEST, REQUEST_V2, REQUEST_AXIS)?;
        let mut axis = [AxisRequest::default(); MAX_AXES];
        for (i, a) in axis[..usize::from(axes)].iter_mut().enumerate() {
            *a = get_request(&p[HEADER + i * REQUEST_AXIS..]);
        }
        let spindle = spindle.then(|| get_request(&p[HEADER + usize::from(axes) * REQUEST_AXIS..]));
        Some(Request {
            seq,
            axes,
            axis,
            spindle,
        })
    }
}

impl Reply {
    pub fn encode(&self, out: &mut [u8; 64]) -> usize {
        let n = usize::from(self.axes.min(MAX_AXES as u8));
        let kind = if self.spindle.is_some() {
            REPLY_V2
        } else {
            REPLY
        };
        out[..HEADER].copy_from_slice(&[kind, self.seq, n as u8]);
        for (i, a) in self.axis[..n].iter().enumerate() {
            put_reply(&mut out[HEADER + i * REPLY_AXIS..], a);
        }
        let mut len = HEADER + n * REPLY_AXIS;
        if let Some(s) = &self.spindle {
            put_reply(&mut out[len..], s);
            len += REPLY_AXIS;
        }
        len
    }

    pub fn decode(p: &[u8]) -> Option<Reply> {
        let (seq, axes, spindle) = header(p, REPLY, REPLY_V2, REPLY_AXIS)?;
        let mut axis = [AxisReply::default(); MAX_AXES];
        for (i, a) in axis[..usize::from(axes)].iter_mut().enumerate() {
            *a = get_reply(&p[HEADER + i * REPLY_AXIS..]);
        }
        let spindle = spindle.then(|| get_reply(&p[HEADER + usize::from(axes) * REPLY_AXIS..]));
        Some(Reply {
            seq,
            axes,
            axis,
            spindle,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn round_trip_and_layout() {
        let mut r = Request {
            seq: 200,
            axes: 2,
            axis: [AxisRequest::default(); MAX_AXES],
            spindle: None,
        };
        r.axis[1] = AxisRequest {
            controlword: 0x000F,
            target_increments: -2,
        };
        let mut b = [0u8; 64];
        let n = r.encode(&mut b);
        assert_eq!(
            &b[..n],
            &[1, 200, 2, 0, 0, 0, 0, 0, 0, 0x0F, 0, 0xFE, 0xFF, 0xFF, 0xFF]
        );
        assert_eq!(Request::decode(&b[..n]), Some(r));
        assert_eq!(Request::decode(&b[..n - 1]), None);
        assert_eq!(Reply::decode(&b[..n]), None);

        let mut y = Reply {
            seq: 7,
            axes: 1,
            axis: [AxisReply::default(); MAX_AXES],
            spindle: None,
        };
        y.axis[0] = AxisReply {
            statusword: 0x1237,
            position_increments: 123_456,
            error_code: 0x8611,
        };
        let n = y.encode(&mut b);
        assert_eq!(n, 11);
        assert_eq!(Reply::decode(&b[..n]), Some(y));
    }

    #[test]
    fn version_2_appends_the_spindle_and_fits_six_axes() {
        let mut r = Request {
            seq: 9,
            axes: 1,
            axis: [AxisRequest::default(); MAX_AXES],
            spindle: Some(AxisRequest {
                controlword: 0x000F,
                target_increments: -12_000,
            }),
        };
        let mut b = [0u8; 64];
        let n = r.encode(&mut b);
        assert_eq!(
            &b[..n],
            &[2, 9, 1, 0, 0, 0, 0, 0, 0, 0x0F, 0, 0x20, 0xD1, 0xFF, 0xFF]
        );
        assert_eq!(Request::decode(&b[..n]), Some(r));
        // A version 2 request without its spindle record is malformed.
        assert_eq!(Request::decode(&b[..n - 6]), None);
        let mut v1 = b;
        v1[0] = REQUEST;
        assert_eq!(Request::decode(&v1[..n]), None, "v1 with a spindle record");

        let mut y = Reply {
            seq: 9,
            axes: 6,
            axis: [AxisReply::default(); MAX_AXES],
            spindle: Some(AxisReply {
                statusword: 0x1237,
                position_increments: 11_990,
                error_code: 0,
            }),
        };
        y.axis[5].position_increments = 5;
        let n = y.encode(&mut b);
        assert_eq!((b[0], n), (REPLY_V2, 3 + 7 * 8));
        assert_eq!(Reply::decode(&b[..n]), Some(y));
        r.axes = 6;
        assert_eq!(r.encode(&mut b), 3 + 7 * 6);
    }
}
