//! Access control of the gRPC API: who is calling (listener, bearer token) and which role the
//! call needs.
//!
//! Every listener wraps its services in [`Auth::interceptor`], which resolves the caller once per
//! call and puts a [`Caller`] into the request's extensions:
//! - a request with `authorization: Bearer <token>` gets the role of that token (tokens are kept
//!   as SHA-256 hashes only); an unknown token is UNAUTHENTICATED on every listener;
//! - without a token, the Unix socket gives `api.local_role` (the socket's mode and group decide
//!   who can connect), loopback TCP gives `api.loopback_role` (default observer: every local
//!   account can open a loopback port), and a remote listener (TLS) refuses the call with
//!   UNAUTHENTICATED.
//!
//! Each RPC then calls [`require`] with the least role it needs (PERMISSION_DENIED below it).
//! Every refusal is logged with the peer and the method.

use std::collections::HashMap;
use std::sync::Arc;

use sha2::{Digest, Sha256};
use tonic::{Request, Status};

use crate::runtime::config::{ApiConfig, Role};

/// Which kind of listener a call came in on.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Trust {
    /// The Unix socket: callers without a token get `local_role`.
    Socket,
    /// Loopback TCP: callers without a token get `loopback_role`.
    Loopback,
    /// Any other address (TLS): a valid token is required.
    Remote,
}

/// The resolved caller of one request.
#[derive(Clone, Debug)]
pub struct Caller {
    pub role: Role,
    /// Token name, or "local" for a local caller without a token.
    pub who: String,
    /// Peer address (TCP) or credentials (Unix socket).
    pub peer: String,
}

/// Token table and local policy.
pub struct Auth {
    tokens: HashMap<[u8; 32], (String, Role)>,
    local_role: Role,
    loopback_role: Role,
}

/// SHA-256 of a token, lower-case hex (what `api.tokens[].sha256` holds).
pub fn hash_token_hex(token: &str) -> String {
    let d = Sha256::digest(token.as_bytes());
    let mut s = String::with_capacity(64);
    for b in d {
        s.push_str(&format!("{b:02x}"));
    }
    s
}

fn parse_hex32(h: &str) -> Option<[u8; 32]> {
    if h.len() != 64 {
        return None;
    }
    let mut out = [0u8; 32];
    for (i, o) in out.iter_mut().enumerate() {
        *o = u8::from_str_radix(h.get(2 * i..2 * i + 2)?, 16).ok()?;
    }
    Some(out)
}

impl Auth {
    pub fn from_config(api: &ApiConfig) -> Arc<Auth> {
        let tokens = api
            .tokens
            .iter()
            .filter_map(|t| parse_hex32(&t.sha256).map(|h| (h, (t.name.clone(), t.role))))
            .collect();
        Arc::new(Auth {
            tokens,
            local_role: api.local_role,
            loopback_role: api.loopback_role,
        })
    }

    /// Resolves the caller of `req` on a listener of kind `trust`.
    pub fn resolve<T>(&self, req: &Request<T>, trust: Trust) -> Result<Caller, Status> {
        let peer = peer_of(req);
        match req.metadata().get("authorization") {
            Some(v) => {
                let text = v.to_str().unwrap_or("");
                let token = text
                    .strip_prefix("Bearer ")
                    .or_else(|| text.strip_prefix("bearer "))
                    .unwrap_or("")
                    .trim();
                let hash: [u8; 32] = Sha256::digest(token.as_bytes()).into();
                match self.tokens.get(&hash) {
                    Some((name, role)) => Ok(Caller {
                        role: *role,
                        who: name.clone(),
                        peer,
                    }),
                    None => {
                        tracing::warn!(%peer, "API call refused: unknown bearer token");
                        Err(Status::unauthenticated("unknown bearer token"))
                    }
                }
            }
            None => match trust {
                Trust::Socket => Ok(Caller {
                    role: self.local_role,
                    who: "local".into(),
                    peer,
                }),
                Trust::Loopback => Ok(Caller {
                    role: self.loopback_role,
                    who: "local".into(),
                    peer,
                }),
                Trust::Remote => {
                    tracing::warn!(%peer, "API call refused: no bearer token on a remote listener");
                    Err(Status::unauthenticated(
                        "a bearer token is required on this listener (authorization: Bearer <token>)",
                    ))
                }
            },
        }
    }

    /// The interceptor of one listener: resolves the caller and stores it in the extensions.
    pub fn interceptor(
        self: &Arc<Self>,
        trust: Trust,
    ) -> impl FnMut(Request<()>) -> Result<Request<()>, Status> + Clone + Send + Sync + 'static
    {
        let auth = self.clone();
        move |mut req: Request<()>| {
            let caller = auth.resolve(&req, trust)?;
            req.extensions_mut().insert(caller);
            Ok(req)
        }
    }
}

/// Peer address of a request, for logs.
pub fn peer_of<T>(req: &Request<T>) -> String {
    if let Some(a) = req.remote_addr() {
        return a.to_string();
    }
    if let Some(u) = req
        .extensions()
        .get::<tonic::transport::server::UdsConnectInfo>()
    {
        return match &u.peer_cred {
            Some(c) => format!(
                "unix socket (uid {}, pid {})",
                c.uid(),
                c.pid().map_or("?".into(), |p| p.to_string())
            ),
            None => "unix socket".into(),
        };
    }
    "unknown peer".into()
}

/// Checks that the caller of `req` has at least `need`; logs and refuses otherwise.
pub fn require<T>(req: &Request<T>, need: Role, method: &str) -> Result<Caller, Status> {
    let Some(caller) = req.extensions().get::<Caller>().cloned() else {
        // A service served without the interceptor: refuse rather than guess.
        tracing::warn!(method, peer = %peer_of(req), "API call refused: caller not resolved");
        return Err(Status::unauthenticated("caller not resolved"));
    };
    if caller.role >= need {
        Ok(caller)
    } else {
        tracing::warn!(
            method,
            peer = %caller.peer,
            who = %caller.who,
            role = caller.role.name(),
            needs = need.name(),
            "API call refused: role too low"
        );
        Err(Status::permission_denied(format!(
            "{method} needs the {} role; this caller ({}) is {}",
            need.name(),
            caller.who,
            caller.role.name()
        )))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn hash_is_sha256_hex() {
        assert_eq!(
            hash_token_hex("abc"),
            "ba7816bf8f01cfea414140de5dae2223b00361a396177a9cb410ff61f20015ad"
        );
        assert!(parse_hex32(&hash_token_hex("x")).is_some());
        assert!(parse_hex32("zz").is_none());
    }
}
