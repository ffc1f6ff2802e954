//! The Error document (`MTConnectError`): why a request was refused.

use super::xml::{HeaderInfo, Xml, attrs};

/// The standard's error codes this agent uses.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ErrorCode {
    /// A sequence number outside the buffer, a count outside 1..=bufferSize.
    OutOfRange,
    /// A parameter that is not a number, or unknown.
    InvalidRequest,
    /// A `path` filter that this agent cannot read, or that selects nothing.
    InvalidPath,
    /// A request this agent does not serve (an unknown URL, a method other than GET).
    InvalidUri,
    /// A device name that is not this machine's.
    NoDevice,
    AssetNotFound,
    /// Too many `/sample` streams at once (`mtconnect.max_streams`).
    TooMany,
    Unsupported,
}

impl ErrorCode {
    pub fn as_str(self) -> &'static str {
        match self {
            ErrorCode::OutOfRange => "OUT_OF_RANGE",
            ErrorCode::InvalidRequest => "INVALID_REQUEST",
            ErrorCode::InvalidPath => "INVALID_PATH",
            ErrorCode::InvalidUri => "INVALID_URI",
            ErrorCode::NoDevice => "NO_DEVICE",
            ErrorCode::AssetNotFound => "ASSET_NOT_FOUND",
            ErrorCode::TooMany => "TOO_MANY",
            ErrorCode::Unsupported => "UNSUPPORTED",
        }
    }

    /// The HTTP status the reference agent answers with.
    pub fn http_status(self) -> u16 {
        match self {
            ErrorCode::NoDevice | ErrorCode::AssetNotFound | ErrorCode::InvalidUri => 404,
            ErrorCode::TooMany => 503,
            ErrorCode::Unsupported => 405,
            _ => 400,
        }
    }
}

/// A refused request: the code and a message saying what to change.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct RequestError {
    pub code: ErrorCode,
    pub message: String,
}

impl RequestError {
    pub fn new(code: ErrorCode, message: impl Into<String>) -> RequestError {
        RequestError {
            code,
            message: message.into(),
        }
    }
}

/// `MTConnectError` with one error.
pub fn write(e: &RequestError, h: &HeaderInfo) -> Vec<u8> {
    let mut x = Xml::new();
    x.root("Error");
    // The Error header has no deviceModelChangeTime.
    let mut a = h.common();
    a.retain(|(k, _)| *k != "deviceModelChangeTime");
    a.push(("bufferSize", h.buffer_size.to_string()));
    x.empty("Header", &attrs(&a));
    x.open("Errors", &[]);
    x.text("Error", &[("errorCode", e.code.as_str())], &e.message);
    x.close("Errors");
    x.close("MTConnectError");
    x.finish()
}
