//! The sockets the API serves on: loopback TCP, other TCP addresses (remote), the Unix socket
//! with its mode and group, and the browser HMI's listener.

use std::path::Path;
use std::sync::Arc;

use tokio::net::{TcpListener, UnixListener};
use tonic::transport::ServerTlsConfig;

use super::ServerError;
use crate::runtime::api::auth::Trust;
use crate::runtime::config::ApiConfig;
use crate::runtime::hmi::Assets;

/// Sockets to serve on, already bound.
#[derive(Default)]
pub struct Listeners {
    /// Loopback TCP: local trust.
    pub local_tcp: Vec<TcpListener>,
    /// Other TCP addresses: TLS (when configured) and a token required.
    pub remote_tcp: Vec<TcpListener>,
    /// The Unix socket: local trust.
    pub unix: Option<UnixListener>,
}

/// Binds `api.extra_listen` and the Unix socket.
pub async fn bind_extra(api: &ApiConfig, storage_dir: &Path) -> Result<Listeners, ServerError> {
    let mut l = Listeners::default();
    // The Unix socket first: no TCP listener of this daemon answers before it exists (a
    // client that finds no socket falls back to TCP, where it would be a mere observer).
    if let Some(path) = api.unix_socket_path(storage_dir) {
        l.unix = Some(bind_unix(
            &path,
            api.socket_mode,
            api.socket_group.as_deref(),
        )?);
    }
    for a in &api.extra_listen {
        let t = TcpListener::bind(a)
            .await
            .map_err(|source| ServerError::Listen {
                key: "api.extra_listen",
                addr: *a,
                source,
            })?;
        if a.ip().is_loopback() {
            l.local_tcp.push(t);
        } else {
            l.remote_tcp.push(t);
        }
    }
    Ok(l)
}

/// A TCP port bound but not yet listening: taken (a second daemon cannot bind it), while a
/// client's connection is refused at once instead of waiting in the backlog for a daemon
/// still starting. [`Reserved::listen`] opens it.
pub struct Reserved {
    socket: tokio::net::TcpSocket,
    pub addr: std::net::SocketAddr,
    key: &'static str,
}

/// How many connections wait to be accepted.
const BACKLOG: u32 = 1024;

impl Reserved {
    /// Binds `addr` for configuration key `key` (its name in the error).
    pub fn bind(key: &'static str, addr: std::net::SocketAddr) -> Result<Reserved, ServerError> {
        let err = |source| ServerError::Listen { key, addr, source };
        let socket = if addr.is_ipv4() {
            tokio::net::TcpSocket::new_v4()
        } else {
            tokio::net::TcpSocket::new_v6()
        }
        .map_err(err)?;
        // As TcpListener::bind: a restart binds again despite connections in TIME_WAIT.
        socket.set_reuseaddr(true).map_err(err)?;
        socket.bind(addr).map_err(err)?;
        let addr = socket.local_addr().map_err(ServerError::LocalAddr)?;
        Ok(Reserved { socket, addr, key })
    }

    pub fn listen(self) -> Result<TcpListener, ServerError> {
        let (key, addr) = (self.key, self.addr);
        self.socket
            .listen(BACKLOG)
            .map_err(|source| ServerError::Listen { key, addr, source })
    }
}

/// Binds the Unix socket: a stale socket file is replaced; mode and group are set before the
/// first connection can be accepted.
pub fn bind_unix(path: &Path, mode: u32, group: Option<&str>) -> Result<UnixListener, ServerError> {
    use std::os::unix::fs::{FileTypeExt, PermissionsExt};
    let err = |source| ServerError::UnixSocket {
        path: path.to_path_buf(),
        source,
    };
    if let Ok(m) = std::fs::symlink_metadata(path) {
        if m.file_type().is_socket() {
            std::fs::remove_file(path).map_err(err)?;
        } else {
            return Err(ServerError::NotASocket {
                path: path.to_path_buf(),
            });
        }
    }
    if let Some(dir) = path.parent().filter(|d| !d.as_os_str().is_empty()) {
        std::fs::create_dir_all(dir).map_err(err)?;
    }
    let l = UnixListener::bind(path).map_err(err)?;
    std::fs::set_permissions(path, std::fs::Permissions::from_mode(mode)).map_err(err)?;
    if let Some(g) = group {
        let gid = group_id(g).ok_or_else(|| ServerError::NoGroup(g.to_string()))?;
        std::os::unix::fs::chown(path, None, Some(gid)).map_err(err)?;
    }
    Ok(l)
}

fn group_id(name: &str) -> Option<u32> {
    let c = std::ffi::CString::new(name).ok()?;
    // SAFETY: getgrnam with a valid C string; the result is read at once (start-up, one thread).
    let g = unsafe { libc::getgrnam(c.as_ptr()) };
    if g.is_null() {
        None
    } else {
        // SAFETY: non-null pointer returned by getgrnam.
        Some(unsafe { (*g).gr_gid })
    }
}

/// The browser HMI's listener (`[hmi] listen`, docs/hmi.md): its static files and every
/// service over grpc-web on one origin.
pub struct HmiListener {
    pub listener: TcpListener,
    pub assets: Arc<Assets>,
    /// Required unless the address is loopback.
    pub tls: Option<ServerTlsConfig>,
}

/// Loopback HMI callers are local (`api.loopback_role` without a token); any other address
/// is remote: TLS and a token.
pub(super) fn hmi_trust(h: &HmiListener) -> Result<Trust, ServerError> {
    let addr = h.listener.local_addr().map_err(ServerError::LocalAddr)?;
    if addr.ip().is_loopback() {
        Ok(Trust::Loopback)
    } else if h.tls.is_some() {
        Ok(Trust::Remote)
    } else {
        Err(ServerError::HmiTlsRequired)
    }
}
