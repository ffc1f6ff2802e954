//! Expedited SDO transfers (values of up to 4 bytes, all start-up configuration needs):
//! the client requests the master sends and the server answers a drive gives.

use super::{Frame, cob};

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Request {
    Download {
        index: u16,
        subindex: u8,
        value: u32,
        size: u8,
    },
    Upload {
        index: u16,
        subindex: u8,
    },
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Response {
    DownloadOk {
        index: u16,
        subindex: u8,
    },
    UploadOk {
        index: u16,
        subindex: u8,
        value: u32,
    },
    Abort {
        index: u16,
        subindex: u8,
        code: u32,
    },
}

impl Response {
    pub fn object(&self) -> (u16, u8) {
        match *self {
            Response::DownloadOk { index, subindex }
            | Response::UploadOk {
                index, subindex, ..
            }
            | Response::Abort {
                index, subindex, ..
            } => (index, subindex),
        }
    }
}

/// Abort codes (CiA 301 table 22) a drive simulator uses.
pub mod abort {
    pub const TIMEOUT: u32 = 0x0504_0000;
    pub const BAD_COMMAND: u32 = 0x0504_0001;
    pub const READ_ONLY: u32 = 0x0601_0002;
    pub const NO_OBJECT: u32 = 0x0602_0000;
    pub const CANNOT_MAP: u32 = 0x0604_0041;
    pub const LENGTH_MISMATCH: u32 = 0x0607_0010;
    pub const NO_SUBINDEX: u32 = 0x0609_0011;
    pub const VALUE_RANGE: u32 = 0x0609_0030;
    pub const GENERAL: u32 = 0x0800_0000;
    pub const DEVICE_STATE: u32 = 0x0800_0022;
}

pub fn abort_text(code: u32) -> &'static str {
    match code {
        abort::TIMEOUT => "SDO protocol timed out",
        abort::BAD_COMMAND => "command not understood",
        abort::READ_ONLY => "object is read-only",
        abort::NO_OBJECT => "object does not exist in the drive",
        abort::CANNOT_MAP => "object cannot be mapped to a PDO",
        abort::LENGTH_MISMATCH => "value has the wrong length",
        abort::NO_SUBINDEX => "sub-index does not exist",
        abort::VALUE_RANGE => "value out of range",
        abort::GENERAL => "general error",
        abort::DEVICE_STATE => "not allowed in the drive's present state",
        _ => "abort code not known, see the drive manual",
    }
}

fn header(cs: u8, index: u16, subindex: u8) -> [u8; 8] {
    let i = index.to_le_bytes();
    [cs, i[0], i[1], subindex, 0, 0, 0, 0]
}

/// Client: write `value` (`size` = 1, 2 or 4 bytes) to `index:subindex` of `node`.
pub fn download(node: u8, index: u16, subindex: u8, value: u32, size: u8) -> Frame {
    let size = size.clamp(1, 4);
    // ccs=1, expedited, size indicated, n = 4 - size unused bytes.
    let mut d = header(0x23 | ((4 - size) << 2), index, subindex);
    d[4..].copy_from_slice(&value.to_le_bytes());
    Frame::new(cob::SDO_RX + u16::from(node), &d)
}

/// Client: read `index:subindex` of `node`.
pub fn upload(node: u8, index: u16, subindex: u8) -> Frame {
    Frame::new(
        cob::SDO_RX + u16::from(node),
        &header(0x40, index, subindex),
    )
}

fn object(p: &[u8]) -> (u16, u8) {
    (u16::from_le_bytes([p[1], p[2]]), p[3])
}

fn value_of(p: &[u8], size: u8) -> u32 {
    let v = u32::from_le_bytes([p[4], p[5], p[6], p[7]]);
    if size >= 4 {
        v
    } else {
        v & ((1u32 << (8 * u32::from(size))) - 1)
    }
}

/// Client: decodes a server answer (COB-ID 0x580 + node); `None` for anything else.
pub fn parse_response(p: &[u8]) -> Option<Response> {
    if p.len() != 8 {
        return None;
    }
    let (index, subindex) = object(p);
    match p[0] >> 5 {
        3 if p[0] == 0x60 => Some(Response::DownloadOk { index, subindex }),
        2 if p[0] & 0x02 != 0 => {
            let size = if p[0] & 0x01 != 0 {
                4 - ((p[0] >> 2) & 0x03)
            } else {
                4
            };
            Some(Response::UploadOk {
                index,
                subindex,
                value: value_of(p, size),
            })
        }
        4 => Some(Response::Abort {
            index,
            subindex,
            code: u32::from_le_bytes([p[4], p[5], p[6], p[7]]),
        }),
        _ => None,
    }
}

/// Server: decodes a client request (COB-ID 0x600 + node). Segmented transfers are not
/// supported and yield `Err(abort code)`.
pub fn parse_request(p: &[u8]) -> Result<Request, u32> {
    if p.len() != 8 {
        return Err(abort::BAD_COMMAND);
    }
    let (index, subindex) = object(p);
    match p[0] >> 5 {
        1 if p[0] & 0x02 != 0 => {
            let size = if p[0] & 0x01 != 0 {
                4 - ((p[0] >> 2) & 0x03)
            } else {
                4
            };
            Ok(Request::Download {
                index,
                subindex,
                value: value_of(p, size),
                size,
            })
        }
        2 => Ok(Request::Upload { index, subindex }),
        _ => Err(abort::BAD_COMMAND),
    }
}

/// Server answers.
pub fn download_ok(node: u8, index: u16, subindex: u8) -> Frame {
    Frame::new(
        cob::SDO_TX + u16::from(node),
        &header(0x60, index, subindex),
    )
}

pub fn upload_ok(node: u8, index: u16, subindex: u8, value: u32, size: u8) -> Frame {
    let size = size.clamp(1, 4);
    let mut d = header(0x43 | ((4 - size) << 2), index, subindex);
    d[4..].copy_from_slice(&value.to_le_bytes());
    Frame::new(cob::SDO_TX + u16::from(node), &d)
}

pub fn abort(node: u8, index: u16, subindex: u8, code: u32) -> Frame {
    let mut d = header(0x80, index, subindex);
    d[4..].copy_from_slice(&code.to_le_bytes());
    Frame::new(cob::SDO_TX + u16::from(node), &d)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn download_round_trip_all_sizes() {
        for (size, value, cs) in [(1u8, 8u32, 0x2F), (2, 4000, 0x2B), (4, 0x6040_0010, 0x23)] {
            let f = download(5, 0x1600, 1, value, size);
            assert_eq!(f.id, 0x605);
            assert_eq!(f.data[0], cs);
            assert_eq!(
                parse_request(f.payload()),
                Ok(Request::Download {
                    index: 0x1600,
                    subindex: 1,
                    value,
                    size
                })
            );
        }
    }

    #[test]
    fn responses_decode() {
        let ok = download_ok(2, 0x6060, 0);
        assert_eq!(ok.id, 0x582);
        assert_eq!(
            parse_response(ok.payload()),
            Some(Response::DownloadOk {
                index: 0x6060,
                subindex: 0
            })
        );
        let up = upload_ok(2, 0x6064, 0, 0xFFFF_FFFE, 4);
        assert_eq!(
            parse_response(up.payload()),
            Some(Response::UploadOk {
                index: 0x6064,
                subindex: 0,
                value: 0xFFFF_FFFE
            })
        );
        let up1 = upload_ok(2, 0x6061, 0, 8, 1);
        assert_eq!(up1.data[0], 0x4F);
        let ab = abort(2, 0x1016, 1, abort::VALUE_RANGE);
        assert_eq!(
            parse_response(ab.payload()),
            Some(Response::Abort {
                index: 0x1016,
                subindex: 1,
                code: abort::VALUE_RANGE
            })
        );
        assert_eq!(parse_response(&[0x60, 0, 0]), None);
        assert_eq!(parse_request(&[0xE0; 8]), Err(abort::BAD_COMMAND));
    }
}
