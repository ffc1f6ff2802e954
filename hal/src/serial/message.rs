//! The two messages of the serial drive protocol (see `hal/SERIAL_PROTOCOL.md`): the
//! controller's request (controlword and target per axis) and the drive's reply (statusword,
//! actual position and error code per axis). Little endian, fixed layout.

use crate::MAX_AXES;

pub const REQUEST: u8 = 0x01;
pub const REPLY: u8 = 0x81;
const HEADER: usize = 3;
const REQUEST_AXIS: usize = 6;
const REPLY_AXIS: usize = 8;

#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct AxisRequest {
    /// CiA 402 controlword.
    pub controlword: u16,
    pub target_increments: i32,
}

#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct AxisReply {
    /// CiA 402 statusword.
    pub statusword: u16,
    pub position_increments: i32,
    /// CiA 402 error code (0x603F), 0 when none.
    pub error_code: u16,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Request {
    pub seq: u8,
    pub axes: u8,
    pub axis: [AxisRequest; MAX_AXES],
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Reply {
    /// Echo of the request's sequence number.
    pub seq: u8,
    pub axes: u8,
    pub axis: [AxisReply; MAX_AXES],
}

fn header(p: &[u8], kind: u8, per_axis: usize) -> Option<(u8, u8)> {
    let (&k, rest) = p.split_first()?;
    let (&seq, rest) = rest.split_first()?;
    let (&axes, rest) = rest.split_first()?;
    (k == kind
        && (1..=MAX_AXES as u8).contains(&axes)
        && rest.len() == per_axis * usize::from(axes))
    .then_some((seq, axes))
}

impl Request {
    /// Writes the payload into `out`; returns its length.
    pub fn encode(&self, out: &mut [u8; 64]) -> usize {
        let n = usize::from(self.axes.min(MAX_AXES as u8));
        out[..HEADER].copy_from_slice(&[REQUEST, self.seq, n as u8]);
        for (i, a) in self.axis[..n].iter().enumerate() {
            let o = HEADER + i * REQUEST_AXIS;
            out[o..o + 2].copy_from_slice(&a.controlword.to_le_bytes());
            out[o + 2..o + 6].copy_from_slice(&a.target_increments.to_le_bytes());
        }
        HEADER + n * REQUEST_AXIS
    }

    pub fn decode(p: &[u8]) -> Option<Request> {
        let (seq, axes) = header(p, REQUEST, REQUEST_AXIS)?;
        let mut axis = [AxisRequest::default(); MAX_AXES];
        for (i, a) in axis[..usize::from(axes)].iter_mut().enumerate() {
            let b = &p[HEADER + i * REQUEST_AXIS..];
            *a = AxisRequest {
                controlword: u16::from_le_bytes([b[0], b[1]]),
                target_increments: i32::from_le_bytes([b[2], b[3], b[4], b[5]]),
            };
        }
        Some(Request { seq, axes, axis })
    }
}

impl Reply {
    pub fn encode(&self, out: &mut [u8; 64]) -> usize {
        let n = usize::from(self.axes.min(MAX_AXES as u8));
        out[..HEADER].copy_from_slice(&[REPLY, self.seq, n as u8]);
        for (i, a) in self.axis[..n].iter().enumerate() {
            let o = HEADER + i * REPLY_AXIS;
            out[o..o + 2].copy_from_slice(&a.statusword.to_le_bytes());
            out[o + 2..o + 6].copy_from_slice(&a.position_increments.to_le_bytes());
            out[o + 6..o + 8].copy_from_slice(&a.error_code.to_le_bytes());
        }
        HEADER + n * REPLY_AXIS
    }

    pub fn decode(p: &[u8]) -> Option<Reply> {
        let (seq, axes) = header(p, REPLY, REPLY_AXIS)?;
        let mut axis = [AxisReply::default(); MAX_AXES];
        for (i, a) in axis[..usize::from(axes)].iter_mut().enumerate() {
            let b = &p[HEADER + i * REPLY_AXIS..];
            *a = AxisReply {
                statusword: u16::from_le_bytes([b[0], b[1]]),
                position_increments: i32::from_le_bytes([b[2], b[3], b[4], b[5]]),
                error_code: u16::from_le_bytes([b[6], b[7]]),
            };
        }
        Some(Reply { seq, axes, axis })
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
}
