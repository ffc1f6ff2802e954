//! The two messages of the serial drive protocol (see `hal/SERIAL_PROTOCOL.md`): the
//! controller's request (controlword and target per axis) and the drive's reply (statusword,
//! actual position and error code per axis). Little endian, fixed layout.
//!
//! Version 1 (types 01h/81h) has axes only. Version 2 (types 02h/82h) appends one record for
//! the spindle drive: its controlword and target velocity, and its statusword, actual
//! velocity and error code. The controller speaks version 2 only when a spindle is configured,
//! so drive units of version 1 keep working unchanged.
//!
//! Version 3 (types 03h/83h, issue #15) adds homing: a flags byte after the axis count says
//! whether the spindle record is present; the request ends with a reference command (set the
//! drive's position reference, idempotent by id), the reply with the home switch inputs and
//! the acknowledgement of the last reference command. The controller speaks version 3 only
//! when homing is configured on the link.

use crate::MAX_AXES;

/// Version 1 request (axes only).
pub const REQUEST: u8 = 0x01;
/// Version 1 reply.
pub const REPLY: u8 = 0x81;
/// Version 2 request: axes, then the spindle.
pub const REQUEST_V2: u8 = 0x02;
/// Version 2 reply: axes, then the spindle.
pub const REPLY_V2: u8 = 0x82;
/// Version 3 request: flags, axes, the spindle if flagged, the reference command.
pub const REQUEST_V3: u8 = 0x03;
/// Version 3 reply: flags, axes, the spindle if flagged, switches and acknowledgement.
pub const REPLY_V3: u8 = 0x83;
/// Version 3 flags bit 0: the spindle record is present.
const FLAG_SPINDLE: u8 = 0x01;
const HEADER: usize = 3;
const HEADER_V3: usize = 4;

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

/// What a version 3 request asks of the drive's position reference.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum HomeAction {
    /// Nothing (the id is the last one the drive acknowledged).
    #[default]
    None,
    /// Add `shift_increments` to the axis's position (actual and target) once per `id`.
    SetReference,
}

/// The reference command of a version 3 request.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct HomeCommand {
    pub action: HomeAction,
    /// Applied once: the drive ignores a command whose id it already acknowledged.
    pub id: u8,
    pub axis: u8,
    /// Shift of the axis's position, increments: new position = old position + shift.
    pub shift_increments: i32,
}

/// Result of the last reference command (version 3 reply).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum HomeResult {
    #[default]
    Applied,
    /// Not applied: the axis does not exist, or the drive cannot redefine its position now.
    Refused,
}

/// Home switches and acknowledgement of a version 3 reply.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct HomeStatus {
    /// Bit i: the home switch input of axis i is active.
    pub switches: u8,
    /// Id of the last reference command the drive handled (0 after power-on).
    pub id: u8,
    pub result: HomeResult,
}

/// One message: the request (records of [`AxisRequest`], a [`HomeCommand`]) or the reply
/// (records of [`AxisReply`], a [`HomeStatus`]); both have the same layout.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Message<R, H> {
    /// The request's sequence number; the reply echoes it.
    pub seq: u8,
    pub axes: u8,
    pub axis: [R; MAX_AXES],
    /// The spindle record: present in versions 2 and 3 only.
    pub spindle: Option<R>,
    /// Version 3 only: the reference command (request), the switches and acknowledgement
    /// (reply).
    pub home: Option<H>,
}

/// The controller's request.
pub type Request = Message<AxisRequest, HomeCommand>;
/// The drive unit's reply.
pub type Reply = Message<AxisReply, HomeStatus>;

/// A fixed-length part of a message, little endian.
pub trait Field: Copy + Default {
    /// Bytes on the wire.
    const LEN: usize;
    fn put(&self, out: &mut [u8]);
    /// `None` for a value the protocol does not define.
    fn get(b: &[u8]) -> Option<Self>;
}

/// The per-axis record of a message kind, and the kind's message types of versions 1, 2, 3.
pub trait Record: Field {
    const TYPES: [u8; 3];
}

impl<R: Record, H: Field> Message<R, H> {
    /// The protocol version of this message (1, 2 or 3).
    pub fn version(&self) -> u8 {
        match (self.home.is_some(), self.spindle.is_some()) {
            (true, _) => 3,
            (false, true) => 2,
            (false, false) => 1,
        }
    }

    /// Writes the payload into `out`; returns its length.
    pub fn encode(&self, out: &mut [u8; 64]) -> usize {
        let n = usize::from(self.axes.min(MAX_AXES as u8));
        let start = put_header(
            out,
            R::TYPES,
            self.version(),
            self.seq,
            n as u8,
            self.spindle.is_some(),
        );
        let mut len = start;
        for r in self.axis[..n].iter().chain(self.spindle.as_ref()) {
            r.put(&mut out[len..]);
            len += R::LEN;
        }
        if let Some(h) = &self.home {
            h.put(&mut out[len..]);
            len += H::LEN;
        }
        len
    }

    pub fn decode(p: &[u8]) -> Option<Self> {
        let l = layout(p, R::TYPES, R::LEN, H::LEN)?;
        let mut axis = [R::default(); MAX_AXES];
        for (i, a) in axis[..usize::from(l.axes)].iter_mut().enumerate() {
            *a = R::get(&p[l.start + i * R::LEN..])?;
        }
        let end = l.start + usize::from(l.axes) * R::LEN;
        let spindle = if l.spindle {
            Some(R::get(&p[end..])?)
        } else {
            None
        };
        let home = if l.v3 {
            Some(H::get(&p[p.len() - H::LEN..])?)
        } else {
            None
        };
        Some(Message {
            seq: l.seq,
            axes: l.axes,
            axis,
            spindle,
            home,
        })
    }
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

/// Layout of a message: sequence number, axis count, whether the spindle record is present,
/// where the records start and whether it is version 3.
struct Layout {
    seq: u8,
    axes: u8,
    spindle: bool,
    start: usize,
    v3: bool,
}

/// The layout of `p` if it is a message of type `v1`, `v2` or `v3` of exactly the right
/// length (`trailer`: the version 3 bytes after the records).
fn layout(p: &[u8], types: [u8; 3], per_axis: usize, trailer: usize) -> Option<Layout> {
    if p.first() != Some(&types[2]) {
        let (seq, axes, spindle) = header(p, types[0], types[1], per_axis)?;
        return Some(Layout {
            seq,
            axes,
            spindle,
            start: HEADER,
            v3: false,
        });
    }
    let [_, seq, axes, flags] = *p.get(..HEADER_V3)? else {
        return None;
    };
    let spindle = flags & FLAG_SPINDLE != 0;
    let records = usize::from(axes) + usize::from(spindle);
    let len = HEADER_V3 + per_axis * records + trailer;
    ((1..=MAX_AXES as u8).contains(&axes) && flags & !FLAG_SPINDLE == 0 && p.len() == len)
        .then_some(Layout {
            seq,
            axes,
            spindle,
            start: HEADER_V3,
            v3: true,
        })
}

impl Field for HomeCommand {
    const LEN: usize = 7;

    fn put(&self, out: &mut [u8]) {
        out[0] = match self.action {
            HomeAction::None => 0,
            HomeAction::SetReference => 1,
        };
        out[1] = self.id;
        out[2] = self.axis;
        out[3..7].copy_from_slice(&self.shift_increments.to_le_bytes());
    }

    fn get(b: &[u8]) -> Option<HomeCommand> {
        let action = match b[0] {
            0 => HomeAction::None,
            1 => HomeAction::SetReference,
            _ => return None,
        };
        Some(HomeCommand {
            action,
            id: b[1],
            axis: b[2],
            shift_increments: i32::from_le_bytes([b[3], b[4], b[5], b[6]]),
        })
    }
}

impl Field for HomeStatus {
    const LEN: usize = 3;

    fn put(&self, out: &mut [u8]) {
        out[0] = self.switches;
        out[1] = self.id;
        out[2] = match self.result {
            HomeResult::Applied => 0,
            HomeResult::Refused => 1,
        };
    }

    fn get(b: &[u8]) -> Option<HomeStatus> {
        let result = match b[2] {
            0 => HomeResult::Applied,
            1 => HomeResult::Refused,
            _ => return None,
        };
        Some(HomeStatus {
            switches: b[0],
            id: b[1],
            result,
        })
    }
}

/// Writes the header of a message of version `version` (types `types` of versions 1, 2, 3);
/// returns where the records start.
fn put_header(out: &mut [u8], types: [u8; 3], version: u8, seq: u8, n: u8, spindle: bool) -> usize {
    match version {
        3 => {
            out[..HEADER_V3].copy_from_slice(&[types[2], seq, n, u8::from(spindle) * FLAG_SPINDLE]);
            HEADER_V3
        }
        v => {
            out[..HEADER].copy_from_slice(&[types[usize::from(v) - 1], seq, n]);
            HEADER
        }
    }
}

impl Field for AxisRequest {
    const LEN: usize = 6;

    fn put(&self, out: &mut [u8]) {
        out[..2].copy_from_slice(&self.controlword.to_le_bytes());
        out[2..6].copy_from_slice(&self.target_increments.to_le_bytes());
    }

    fn get(b: &[u8]) -> Option<AxisRequest> {
        Some(AxisRequest {
            controlword: u16::from_le_bytes([b[0], b[1]]),
            target_increments: i32::from_le_bytes([b[2], b[3], b[4], b[5]]),
        })
    }
}

impl Record for AxisRequest {
    const TYPES: [u8; 3] = [REQUEST, REQUEST_V2, REQUEST_V3];
}

impl Field for AxisReply {
    const LEN: usize = 8;

    fn put(&self, out: &mut [u8]) {
        out[..2].copy_from_slice(&self.statusword.to_le_bytes());
        out[2..6].copy_from_slice(&self.position_increments.to_le_bytes());
        out[6..8].copy_from_slice(&self.error_code.to_le_bytes());
    }

    fn get(b: &[u8]) -> Option<AxisReply> {
        Some(AxisReply {
            statusword: u16::from_le_bytes([b[0], b[1]]),
            position_increments: i32::from_le_bytes([b[2], b[3], b[4], b[5]]),
            error_code: u16::from_le_bytes([b[6], b[7]]),
        })
    }
}

impl Record for AxisReply {
    const TYPES: [u8; 3] = [REPLY, REPLY_V2, REPLY_V3];
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
            home: None,
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
            home: None,
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
            home: None,
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
            home: None,
        };
        y.axis[5].position_increments = 5;
        let n = y.encode(&mut b);
        assert_eq!((b[0], n), (REPLY_V2, 3 + 7 * 8));
        assert_eq!(Reply::decode(&b[..n]), Some(y));
        r.axes = 6;
        assert_eq!(r.encode(&mut b), 3 + 7 * 6);
    }

    #[test]
    fn version_3_carries_the_reference_command_and_the_switches() {
        let mut r = Request {
            seq: 4,
            axes: 2,
            axis: [AxisRequest::default(); MAX_AXES],
            spindle: None,
            home: Some(HomeCommand {
                action: HomeAction::SetReference,
                id: 7,
                axis: 1,
                shift_increments: -3,
            }),
        };
        let mut b = [0u8; 64];
        let n = r.encode(&mut b);
        assert_eq!(&b[..4], &[REQUEST_V3, 4, 2, 0]);
        assert_eq!(&b[n - 7..n], &[1, 7, 1, 0xFD, 0xFF, 0xFF, 0xFF]);
        assert_eq!(Request::decode(&b[..n]), Some(r));
        assert_eq!(Request::decode(&b[..n - 1]), None);
        let mut bad = b;
        bad[n - 7] = 9;
        assert_eq!(Request::decode(&bad[..n]), None, "unknown action");
        r.spindle = Some(AxisRequest::default());
        let n = r.encode(&mut b);
        assert_eq!(b[3], FLAG_SPINDLE);
        assert_eq!(Request::decode(&b[..n]), Some(r));

        // Six axes, the spindle and the trailer still fit 64 bytes.
        let y = Reply {
            seq: 4,
            axes: 6,
            axis: [AxisReply::default(); MAX_AXES],
            spindle: Some(AxisReply::default()),
            home: Some(HomeStatus {
                switches: 0b10_0001,
                id: 7,
                result: HomeResult::Refused,
            }),
        };
        let n = y.encode(&mut b);
        assert_eq!((b[0], n), (REPLY_V3, 4 + 7 * 8 + 3));
        assert_eq!(Reply::decode(&b[..n]), Some(y));
        assert_eq!(y.version(), 3);
        // Versions 1 and 2 decode as before: no home record.
        let v2 = Reply { home: None, ..y };
        let n = v2.encode(&mut b);
        assert_eq!(b[0], REPLY_V2);
        assert_eq!(Reply::decode(&b[..n]).unwrap().home, None);
    }
}
