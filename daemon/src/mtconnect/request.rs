//! MTConnect requests (Part 1, *REST*): the URL and query of a GET, checked. Every refusal is
//! an [`RequestError`] that becomes an MTConnectError document.

use percent_encoding::percent_decode_str;

use super::error::{ErrorCode, RequestError};

/// Heartbeat of a `/sample` stream when nothing changes, ms (the standard's default).
pub const DEFAULT_HEARTBEAT_MS: u64 = 10_000;
/// Observations per `/sample` document unless asked otherwise.
pub const DEFAULT_COUNT: u64 = 100;

/// A request this agent serves.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Request {
    Probe,
    Current {
        at: Option<u64>,
        path: Option<String>,
        /// Stream a current document every `interval` ms.
        interval_ms: Option<u64>,
    },
    Sample {
        from: Option<u64>,
        count: u64,
        path: Option<String>,
        interval_ms: Option<u64>,
        heartbeat_ms: u64,
    },
    /// `/assets` (all) or `/asset/T01;T02`.
    Assets {
        ids: Option<Vec<String>>,
    },
}

impl Request {
    pub fn interval_ms(&self) -> Option<u64> {
        match self {
            Request::Current { interval_ms, .. } | Request::Sample { interval_ms, .. } => {
                *interval_ms
            }
            _ => None,
        }
    }
}

fn invalid(msg: String) -> RequestError {
    RequestError::new(ErrorCode::InvalidRequest, msg)
}

/// The decoded query parameters.
struct Query(Vec<(String, String)>);

impl Query {
    fn parse(q: &str) -> Query {
        let dec = |s: &str| {
            percent_decode_str(&s.replace('+', " "))
                .decode_utf8_lossy()
                .into_owned()
        };
        Query(
            q.split('&')
                .filter(|p| !p.is_empty())
                .map(|p| match p.split_once('=') {
                    Some((k, v)) => (dec(k), dec(v)),
                    None => (dec(p), String::new()),
                })
                .collect(),
        )
    }

    fn get(&self, k: &str) -> Option<&str> {
        self.0.iter().find(|(n, _)| n == k).map(|(_, v)| v.as_str())
    }

    fn only(&self, allowed: &[&str]) -> Result<(), RequestError> {
        match self.0.iter().find(|(k, _)| !allowed.contains(&k.as_str())) {
            Some((k, _)) => Err(invalid(format!(
                "unknown parameter '{k}' (this request takes: {})",
                allowed.join(", ")
            ))),
            None => Ok(()),
        }
    }

    fn number(&self, k: &'static str) -> Result<Option<u64>, RequestError> {
        match self.get(k) {
            None => Ok(None),
            Some(v) => {
                v.trim().parse::<u64>().map(Some).map_err(|_| {
                    invalid(format!("'{k}' must be a non-negative integer, it is {v:?}"))
                })
            }
        }
    }
}

/// Parses a GET of `path?query` for the device named `device`; `buffer_size` bounds `count`.
pub fn parse(
    path: &str,
    query: &str,
    device: &str,
    buffer_size: usize,
) -> Result<Request, RequestError> {
    let q = Query::parse(query);
    let mut segs: Vec<String> = path
        .split('/')
        .filter(|s| !s.is_empty())
        .map(|s| percent_decode_str(s).decode_utf8_lossy().into_owned())
        .collect();
    // `/{device}/probe`: the device must be this one.
    let known = ["probe", "current", "sample", "assets", "asset"];
    if segs.first().is_some_and(|s| !known.contains(&s.as_str())) {
        let d = segs.remove(0);
        if d != device {
            return Err(RequestError::new(
                ErrorCode::NoDevice,
                format!("no device named {d:?}: this agent serves {device:?} (see /probe)"),
            ));
        }
    }
    let segs: Vec<&str> = segs.iter().map(String::as_str).collect();
    match segs.as_slice() {
        [] | ["probe"] => {
            q.only(&["device"])?;
            Ok(Request::Probe)
        }
        ["current"] => current(&q),
        ["sample"] => sample(&q, buffer_size),
        ["assets"] => {
            q.only(&["type", "removed", "count", "device"])?;
            Ok(Request::Assets { ids: None })
        }
        ["asset", ids] | ["assets", ids] => Ok(Request::Assets {
            ids: Some(ids.split(';').map(str::to_string).collect()),
        }),
        _ => Err(RequestError::new(
            ErrorCode::InvalidUri,
            format!("{path:?} is not a request of this agent: /probe, /current, /sample, /assets"),
        )),
    }
}

fn current(q: &Query) -> Result<Request, RequestError> {
    q.only(&["at", "path", "interval", "device"])?;
    let at = q.number("at")?;
    let interval_ms = q.number("interval")?;
    if at.is_some() && interval_ms.is_some() {
        return Err(invalid(
            "'at' and 'interval' cannot be used together".into(),
        ));
    }
    Ok(Request::Current {
        at,
        path: q.get("path").map(str::to_string),
        interval_ms,
    })
}

fn sample(q: &Query, buffer_size: usize) -> Result<Request, RequestError> {
    q.only(&["from", "count", "path", "interval", "heartbeat", "device"])?;
    let count = match q.get("count") {
        None => DEFAULT_COUNT,
        Some(v) => {
            let n: i64 = v
                .trim()
                .parse()
                .map_err(|_| invalid(format!("'count' must be an integer, it is {v:?}")))?;
            if n < 1 || n as u64 > buffer_size as u64 {
                return Err(RequestError::new(
                    ErrorCode::OutOfRange,
                    format!(
                        "'count' must be between 1 and {buffer_size} (the buffer size), it is {n}"
                    ),
                ));
            }
            n as u64
        }
    };
    Ok(Request::Sample {
        from: q.number("from")?,
        count,
        path: q.get("path").map(str::to_string),
        interval_ms: q.number("interval")?,
        heartbeat_ms: q
            .number("heartbeat")?
            .unwrap_or(DEFAULT_HEARTBEAT_MS)
            .max(1),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn requests_parse_and_bad_ones_get_their_codes() {
        assert_eq!(parse("/probe", "", "m", 10).unwrap(), Request::Probe);
        assert_eq!(parse("/m/probe", "", "m", 10).unwrap(), Request::Probe);
        assert_eq!(
            parse("/other/probe", "", "m", 10).unwrap_err().code,
            ErrorCode::NoDevice
        );
        assert_eq!(
            parse("/current", "path=//Linear%5B@name=%22X%22%5D&at=5", "m", 10).unwrap(),
            Request::Current {
                at: Some(5),
                path: Some("//Linear[@name=\"X\"]".into()),
                interval_ms: None
            }
        );
        let e = |q: &str| parse("/sample", q, "m", 10).unwrap_err().code;
        assert_eq!(e("count=0"), ErrorCode::OutOfRange);
        assert_eq!(e("count=11"), ErrorCode::OutOfRange);
        assert_eq!(e("count=x"), ErrorCode::InvalidRequest);
        assert_eq!(e("from=-1"), ErrorCode::InvalidRequest);
        assert_eq!(e("frm=1"), ErrorCode::InvalidRequest);
        assert_eq!(
            parse("/nothing/here", "", "m", 10).unwrap_err().code,
            ErrorCode::NoDevice
        );
        assert_eq!(
            parse("/m/here", "", "m", 10).unwrap_err().code,
            ErrorCode::InvalidUri
        );
    }
}
