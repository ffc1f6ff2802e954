//! The gRPC codec of `cnc.v1`: prost encoding, with refusals a client can act on.
//!
//! prost refuses a message whose `string` field is not UTF-8, and tonic's own codec reports
//! that as INTERNAL without saying where. A program text from a PC editor in a legacy code
//! page is an input mistake: this codec answers INVALID_ARGUMENT naming the field, the line,
//! the column and the byte offset of the first bad byte, with a `cnc.v1.Diagnostics` detail
//! (the same shape as program errors). Any other undecodable message is INVALID_ARGUMENT too.

use std::marker::PhantomData;

use prost::Message;
use prost::bytes::Buf;
use tonic::codec::{Codec, DecodeBuf, Decoder};
use tonic::{Code, Status};
use tonic_prost::ProstEncoder;

/// prost encoding; decoding errors as INVALID_ARGUMENT with a location.
#[derive(Debug, Clone)]
pub struct CncCodec<T, U> {
    _pd: PhantomData<(T, U)>,
}

impl<T, U> Default for CncCodec<T, U> {
    fn default() -> Self {
        CncCodec { _pd: PhantomData }
    }
}

impl<T, U> Codec for CncCodec<T, U>
where
    T: Message + Send + 'static,
    U: Message + Default + Send + 'static,
{
    type Encode = T;
    type Decode = U;
    type Encoder = ProstEncoder<T>;
    type Decoder = CncDecoder<U>;

    fn encoder(&mut self) -> Self::Encoder {
        ProstEncoder::default()
    }

    fn decoder(&mut self) -> Self::Decoder {
        CncDecoder { _pd: PhantomData }
    }
}

/// Decodes `U`; see the module documentation for the refusals.
#[derive(Debug, Clone)]
pub struct CncDecoder<U> {
    _pd: PhantomData<U>,
}

impl<U: Message + Default> Decoder for CncDecoder<U> {
    type Item = U;
    type Error = Status;

    fn decode(&mut self, buf: &mut DecodeBuf<'_>) -> Result<Option<U>, Status> {
        let len = buf.remaining();
        // tonic hands over one contiguous buffer; decode from the slice so the raw bytes are
        // still there to locate an error.
        let raw = buf.chunk();
        if raw.len() < len {
            return U::decode(buf)
                .map(Some)
                .map_err(|e| Status::invalid_argument(e.to_string()));
        }
        let out = U::decode(raw).map_err(|e| refusal(&e, raw));
        buf.advance(len);
        out.map(Some)
    }
}

/// Where the first byte that is not UTF-8 is in a text.
#[derive(Debug, PartialEq, Eq)]
pub struct BadUtf8 {
    /// 1-based line and column (column in characters before the bad byte, plus one).
    pub line: u32,
    pub column: u32,
    /// Byte offset in the text.
    pub offset: usize,
}

/// Locates the first invalid UTF-8 byte of `text`, or `None` when it is valid.
pub fn locate_bad_utf8(text: &[u8]) -> Option<BadUtf8> {
    let offset = std::str::from_utf8(text).err()?.valid_up_to();
    let good = std::str::from_utf8(&text[..offset]).unwrap_or_default();
    let line_start = good.rfind('\n').map_or(0, |k| k + 1);
    Some(BadUtf8 {
        line: good.matches('\n').count() as u32 + 1,
        column: good[line_start..].chars().count() as u32 + 1,
        offset,
    })
}

fn refusal(e: &prost::DecodeError, raw: &[u8]) -> Status {
    let what = e.to_string();
    if !what.contains("UTF-8") {
        return Status::invalid_argument(format!("the request does not decode: {what}"));
    }
    let field = what
        .split(": ")
        .find(|p| p.contains('.') && !p.contains(' '))
        .unwrap_or("a text field");
    let Some((number, at)) = first_bad_text_field(raw) else {
        return Status::invalid_argument(format!("{field} is not UTF-8 text"));
    };
    let msg = format!(
        "{field} (field {number}) is not UTF-8 text: the first bad byte is at line {}, column {} \
         (byte offset {}); save the file as UTF-8",
        at.line, at.column, at.offset
    );
    let details = crate::v1::Diagnostics {
        items: vec![crate::v1::Diagnostic {
            severity: crate::v1::Severity::Error as i32,
            block: None,
            line: at.line,
            column: at.column,
            message: msg.clone(),
            // kernel::DiagCode::TextNotUtf8 (this crate does not depend on the kernel).
            code: "text_not_utf8".into(),
            ..Default::default()
        }],
        totals: Some(crate::v1::DiagnosticCounts {
            errors: 1,
            ..Default::default()
        }),
    }
    .encode_to_vec();
    Status::with_details(Code::InvalidArgument, msg, details.into())
}

/// The first top-level length-delimited field that is not UTF-8: its number and where.
fn first_bad_text_field(mut raw: &[u8]) -> Option<(u32, BadUtf8)> {
    while !raw.is_empty() {
        let key = prost::encoding::decode_varint(&mut raw).ok()?;
        let (number, wire) = ((key >> 3) as u32, key & 7);
        match wire {
            0 => {
                prost::encoding::decode_varint(&mut raw).ok()?;
            }
            1 => raw = raw.get(8..)?,
            5 => raw = raw.get(4..)?,
            2 => {
                let n = prost::encoding::decode_varint(&mut raw).ok()? as usize;
                let (field, rest) = (raw.get(..n)?, raw.get(n..)?);
                if let Some(at) = locate_bad_utf8(field) {
                    return Some((number, at));
                }
                raw = rest;
            }
            _ => return None,
        }
    }
    None
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn locates_the_first_bad_byte() {
        assert_eq!(locate_bad_utf8(b"G1 X1\n"), None);
        let at = locate_bad_utf8(b"N10 G1\nN20 (\xe8ep)\n").unwrap();
        assert_eq!((at.line, at.column, at.offset), (2, 6, 12));
    }

    #[test]
    fn finds_the_field() {
        let mut raw = crate::v1::LoadProgramRequest {
            name: "a".into(),
            text: String::new(),
            dialect: String::new(),
        }
        .encode_to_vec();
        // field 2, length 3: "X\xffY"
        raw.extend_from_slice(&[0x12, 3, b'X', 0xff, b'Y']);
        let (n, at) = first_bad_text_field(&raw).unwrap();
        assert_eq!((n, at.line, at.column, at.offset), (2, 1, 2, 1));
        let e = crate::v1::LoadProgramRequest::decode(&raw[..]).unwrap_err();
        let s = refusal(&e, &raw);
        assert_eq!(s.code(), Code::InvalidArgument);
        assert!(
            s.message().contains("LoadProgramRequest.text"),
            "{}",
            s.message()
        );
    }
}
