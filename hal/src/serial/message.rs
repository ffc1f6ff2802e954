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
//!
//! Version 4 (types 04h/84h) adds the unit's digital I/O: the version 3 layout, its flags
//! byte saying whether the spindle record and the homing record are present, then the I/O
//! record: the request's 64-bit output word (and, while the unit has not confirmed it, the
//! safe output word it falls to on link loss), the reply's 64-bit input word. The controller
//! speaks version 4 only when I/O points are wired to the unit.

use super::frame::MAX_PAYLOAD;
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
/// Version 4 request: flags, axes, the spindle and the reference command if flagged, the
/// output word, the safe output word if flagged.
pub const REQUEST_V4: u8 = 0x04;
/// Version 4 reply: flags, axes, the spindle and the homing record if flagged, the input word.
pub const REPLY_V4: u8 = 0x84;
/// Versions 3 and 4, flags bit 0: the spindle record is present.
const FLAG_SPINDLE: u8 = 0x01;
/// Version 4 flags bit 1: the homing record (reference command, switches) is present.
const FLAG_HOME: u8 = 0x02;
/// Version 4 flags bit 2: in a request, the safe output word follows the output word; in a
/// reply, the unit holds the safe output word of the request it answers.
const FLAG_SAFE: u8 = 0x04;
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

/// The I/O record of a version 4 request.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct IoCommand {
    /// The unit's output word: bit i drives the unit's output i.
    pub outputs: u64,
    /// The word the unit's outputs fall to when no valid request arrives for its watchdog
    /// time. Sent until a reply confirms it (flags bit 2), then left out.
    pub safe_outputs: Option<u64>,
}

/// The I/O record of a version 4 reply.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct IoStatus {
    /// The unit's input word: bit i is the unit's input i as the wire reads it.
    pub inputs: u64,
    /// The unit holds a safe output word (flags bit 2): the one of the request answered, if
    /// that request carried one.
    pub safe_held: bool,
}

/// One message: the request (records of [`AxisRequest`], a [`HomeCommand`], an
/// [`IoCommand`]) or the reply (records of [`AxisReply`], a [`HomeStatus`], an [`IoStatus`]);
/// both have the same layout.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Message<R, H, I> {
    /// The request's sequence number; the reply echoes it.
    pub seq: u8,
    pub axes: u8,
    pub axis: [R; MAX_AXES],
    /// The spindle record: present in versions 2 and 3 only.
    pub spindle: Option<R>,
    /// Versions 3 and 4: the reference command (request), the switches and acknowledgement
    /// (reply); always present in version 3, flagged in version 4.
    pub home: Option<H>,
    /// Version 4 only: the output words (request), the input word (reply).
    pub io: Option<I>,
}

/// The controller's request.
pub type Request = Message<AxisRequest, HomeCommand, IoCommand>;
/// The drive unit's reply.
pub type Reply = Message<AxisReply, HomeStatus, IoStatus>;

/// A fixed-length part of a message, little endian.
pub trait Field: Copy + Default {
    /// Bytes on the wire.
    const LEN: usize;
    fn put(&self, out: &mut [u8]);
    /// `None` for a value the protocol does not define.
    fn get(b: &[u8]) -> Option<Self>;
}

/// The per-axis record of a message kind, and the kind's message types of versions 1 to 4.
pub trait Record: Field {
    const TYPES: [u8; 4];
}

/// The I/O record of a message kind (version 4): its length depends on flags bit 2.
pub trait IoField: Copy + Default {
    /// Whether the record sets flags bit 2.
    fn flag(&self) -> bool;
    /// Bytes on the wire with flags bit 2 set or clear.
    fn len(flag: bool) -> usize;
    fn put(&self, out: &mut [u8]);
    fn get(b: &[u8], flag: bool) -> Option<Self>;
}

impl<R: Record, H: Field, I: IoField> Message<R, H, I> {
    /// The protocol version of this message (1 to 4).
    pub fn version(&self) -> u8 {
        match (
            self.io.is_some(),
            self.home.is_some(),
            self.spindle.is_some(),
        ) {
            (true, _, _) => 4,
            (false, true, _) => 3,
            (false, false, true) => 2,
            (false, false, false) => 1,
        }
    }

    /// The flags byte of versions 3 and 4.
    fn flags(&self) -> u8 {
        let mut flags = u8::from(self.spindle.is_some()) * FLAG_SPINDLE;
        if let Some(io) = &self.io {
            flags |=
                (u8::from(self.home.is_some()) * FLAG_HOME) | (u8::from(io.flag()) * FLAG_SAFE);
        }
        flags
    }

    /// Writes the payload into `out`; returns its length.
    pub fn encode(&self, out: &mut [u8; MAX_PAYLOAD]) -> usize {
        let n = usize::from(self.axes.min(MAX_AXES as u8));
        let header = [R::TYPES[usize::from(self.version()) - 1], self.seq, n as u8];
        out[..HEADER].copy_from_slice(&header);
        let mut len = HEADER;
        if self.version() >= 3 {
            out[len] = self.flags();
            len += 1;
        }
        for r in self.axis[..n].iter().chain(self.spindle.as_ref()) {
            r.put(&mut out[len..]);
            len += R::LEN;
        }
        if let Some(h) = &self.home {
            h.put(&mut out[len..]);
            len += H::LEN;
        }
        if let Some(io) = &self.io {
            io.put(&mut out[len..]);
            len += I::len(io.flag());
        }
        len
    }

    pub fn decode(p: &[u8]) -> Option<Self> {
        let l = layout(p, R::TYPES, R::LEN, H::LEN, I::len)?;
        let mut at = l.start;
        let mut next = |len: usize| {
            at += len;
            &p[at - len..]
        };
        let mut axis = [R::default(); MAX_AXES];
        for a in &mut axis[..usize::from(l.axes)] {
            *a = R::get(next(R::LEN))?;
        }
        let spindle = l.spindle.then(|| R::get(next(R::LEN))).flatten();
        let home = l.home.then(|| H::get(next(H::LEN))).flatten();
        let io = l.io.and_then(|flag| I::get(next(I::len(flag)), flag));
        // A record the protocol does not define makes the whole message malformed.
        if spindle.is_some() != l.spindle
            || home.is_some() != l.home
            || io.is_some() != l.io.is_some()
        {
            return None;
        }
        Some(Message {
            seq: l.seq,
            axes: l.axes,
            axis,
            spindle,
            home,
            io,
        })
    }
}

/// Layout of a message: sequence number, axis count, which records are present and where
/// the records start.
struct Layout {
    seq: u8,
    axes: u8,
    spindle: bool,
    start: usize,
    /// The homing record (version 3, or flagged in version 4).
    home: bool,
    /// Version 4: the I/O record, with flags bit 2 set or clear.
    io: Option<bool>,
}

/// The layout of `p` if it is a message of one of the kind's `types` (versions 1 to 4) of
/// exactly the right length (`per_axis`: a record's length; `home_len`: the homing record's;
/// `io_len`: the I/O record's given flags bit 2).
fn layout(
    p: &[u8],
    types: [u8; 4],
    per_axis: usize,
    home_len: usize,
    io_len: fn(bool) -> usize,
) -> Option<Layout> {
    let version = 1 + types.iter().position(|t| p.first() == Some(t))?;
    let [_, seq, axes] = *p.get(..HEADER)? else {
        return None;
    };
    let (start, flags) = match version {
        1 => (HEADER, 0),
        2 => (HEADER, FLAG_SPINDLE),
        _ => (HEADER_V3, *p.get(HEADER)?),
    };
    let allowed = match version {
        1 | 2 => flags,
        3 => FLAG_SPINDLE,
        _ => FLAG_SPINDLE | FLAG_HOME | FLAG_SAFE,
    };
    let spindle = flags & FLAG_SPINDLE != 0;
    let home = version == 3 || flags & FLAG_HOME != 0;
    let io = (version == 4).then_some(flags & FLAG_SAFE != 0);
    let records = usize::from(axes) + usize::from(spindle);
    let len = start + per_axis * records + if home { home_len } else { 0 } + io.map_or(0, io_len);
    ((1..=MAX_AXES as u8).contains(&axes) && flags & !allowed == 0 && p.len() == len).then_some(
        Layout {
            seq,
            axes,
            spindle,
            start,
            home,
            io,
        },
    )
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

/// A 64-bit word, little endian, at the start of `b`.
fn word(b: &[u8]) -> Option<u64> {
    Some(u64::from_le_bytes(b.get(..8)?.try_into().ok()?))
}

impl IoField for IoCommand {
    fn flag(&self) -> bool {
        self.safe_outputs.is_some()
    }

    fn len(flag: bool) -> usize {
        8 + 8 * usize::from(flag)
    }

    fn put(&self, out: &mut [u8]) {
        out[..8].copy_from_slice(&self.outputs.to_le_bytes());
        if let Some(safe) = self.safe_outputs {
            out[8..16].copy_from_slice(&safe.to_le_bytes());
        }
    }

    fn get(b: &[u8], flag: bool) -> Option<IoCommand> {
        Some(IoCommand {
            outputs: word(b)?,
            safe_outputs: if flag { Some(word(&b[8..])?) } else { None },
        })
    }
}

impl IoField for IoStatus {
    fn flag(&self) -> bool {
        self.safe_held
    }

    fn len(_: bool) -> usize {
        8
    }

    fn put(&self, out: &mut [u8]) {
        out[..8].copy_from_slice(&self.inputs.to_le_bytes());
    }

    fn get(b: &[u8], flag: bool) -> Option<IoStatus> {
        Some(IoStatus {
            inputs: word(b)?,
            safe_held: flag,
        })
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
    const TYPES: [u8; 4] = [REQUEST, REQUEST_V2, REQUEST_V3, REQUEST_V4];
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
    const TYPES: [u8; 4] = [REPLY, REPLY_V2, REPLY_V3, REPLY_V4];
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
            io: None,
        };
        r.axis[1] = AxisRequest {
            controlword: 0x000F,
            target_increments: -2,
        };
        let mut b = [0u8; MAX_PAYLOAD];
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
            io: None,
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
            io: None,
        };
        let mut b = [0u8; MAX_PAYLOAD];
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
            io: None,
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
            io: None,
        };
        let mut b = [0u8; MAX_PAYLOAD];
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
            io: None,
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

    #[test]
    fn version_4_carries_the_io_words_and_the_safe_word_when_flagged() {
        let mut axis = [AxisRequest::default(); MAX_AXES];
        axis[0].controlword = 0x000F;
        let mut r = Request {
            seq: 5,
            axes: 1,
            axis,
            spindle: None,
            home: None,
            io: Some(IoCommand {
                outputs: 0x8000_0000_0000_0001,
                safe_outputs: Some(0x0100),
            }),
        };
        let mut b = [0u8; MAX_PAYLOAD];
        let n = r.encode(&mut b);
        assert_eq!(&b[..4], &[REQUEST_V4, 5, 1, FLAG_SAFE]);
        assert_eq!(n, 4 + 6 + 16);
        assert_eq!(&b[10..18], &[1, 0, 0, 0, 0, 0, 0, 0x80]);
        assert_eq!(&b[18..26], &[0, 1, 0, 0, 0, 0, 0, 0]);
        assert_eq!(Request::decode(&b[..n]), Some(r));
        assert_eq!(
            Request::decode(&b[..n - 8]),
            None,
            "flagged but no safe word"
        );
        let mut bad = b;
        bad[3] |= 0x08;
        assert_eq!(Request::decode(&bad[..n]), None, "unknown flag");
        // Once confirmed the safe word is left out; homing is flagged.
        r.io = Some(IoCommand {
            outputs: 3,
            safe_outputs: None,
        });
        r.home = Some(HomeCommand::default());
        let n = r.encode(&mut b);
        assert_eq!((b[3], n), (FLAG_HOME, 4 + 6 + 7 + 8));
        assert_eq!(Request::decode(&b[..n]), Some(r));

        // The largest reply: six axes, the spindle, homing and the input word.
        let y = Reply {
            seq: 5,
            axes: 6,
            axis: [AxisReply::default(); MAX_AXES],
            spindle: Some(AxisReply::default()),
            home: Some(HomeStatus::default()),
            io: Some(IoStatus {
                inputs: 1 << 63 | 2,
                safe_held: true,
            }),
        };
        let n = y.encode(&mut b);
        assert_eq!(
            b[..4],
            [REPLY_V4, 5, 6, FLAG_SPINDLE | FLAG_HOME | FLAG_SAFE]
        );
        assert_eq!((y.version(), n), (4, 4 + 7 * 8 + 3 + 8));
        assert_eq!(Reply::decode(&b[..n]), Some(y));
        // Older versions decode as before: no I/O record.
        let v3 = Reply { io: None, ..y };
        let n = v3.encode(&mut b);
        assert_eq!((b[0], b[3], n), (REPLY_V3, FLAG_SPINDLE, 63));
        assert_eq!(Reply::decode(&b[..n]), Some(v3));
    }
}
