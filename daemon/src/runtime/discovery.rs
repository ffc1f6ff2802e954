//! Where a running `cncd` can be reached, published for `cncctl` (issue #31: cncctl finds its
//! daemon whatever the data directory).
//!
//! `cncd` writes the absolute path of its Unix socket to `cncd.addr` in a per-user runtime
//! directory ([`runtime_dir`]) once the socket is bound, and removes it at a clean stop when it
//! still names its socket. `cncctl` reads it when no `--addr`, `$CNCCTL_ADDR` or `--config`
//! says where to go. The last `cncd` started by a user is the one published; a stale file (the
//! daemon was killed) names a socket nobody answers on and is skipped.

use std::path::{Path, PathBuf};

use super::config::Config;
use super::storage::write_atomic;

/// Environment variable that overrides the runtime directory (tests, several daemons).
pub const RUNTIME_DIR_ENV: &str = "CNCD_RUNTIME_DIR";

/// The file in the runtime directory that names the socket.
pub const ADDR_FILE: &str = "cncd.addr";

/// The per-user runtime directory: `$CNCD_RUNTIME_DIR`, else `$XDG_RUNTIME_DIR/cncd`, else
/// `/run/user/<uid>/cncd` where that exists, else `<temp dir>/cncd-<uid>`.
pub fn runtime_dir() -> PathBuf {
    if let Some(d) = std::env::var_os(RUNTIME_DIR_ENV).filter(|d| !d.is_empty()) {
        return PathBuf::from(d);
    }
    if let Some(d) = std::env::var_os("XDG_RUNTIME_DIR").filter(|d| !d.is_empty()) {
        return PathBuf::from(d).join("cncd");
    }
    // SAFETY: getuid has no preconditions and cannot fail.
    let uid = unsafe { libc::getuid() };
    let user_run = PathBuf::from(format!("/run/user/{uid}"));
    if user_run.is_dir() {
        return user_run.join("cncd");
    }
    std::env::temp_dir().join(format!("cncd-{uid}"))
}

/// The socket `config` serves, absolute (relative paths are taken from the current directory,
/// as cncd takes them).
pub fn socket_of(config: &Config) -> Option<PathBuf> {
    let p = config.api.unix_socket_path(&config.storage.dir)?;
    Some(absolute(&p))
}

fn absolute(p: &Path) -> PathBuf {
    if p.is_absolute() {
        return p.to_owned();
    }
    std::env::current_dir().map_or_else(|_| p.to_owned(), |d| d.join(p))
}

/// Publishes `socket` (called by cncd once it is bound). Failing to publish is not fatal.
pub fn publish(socket: &Path) {
    let dir = runtime_dir();
    let r = std::fs::create_dir_all(&dir).and_then(|()| {
        use std::os::unix::fs::PermissionsExt;
        // Per user: others need not learn where the socket is.
        let _ = std::fs::set_permissions(&dir, std::fs::Permissions::from_mode(0o700));
        let text = format!("unix:{}\n", absolute(socket).display());
        write_atomic(&dir.join(ADDR_FILE), text.as_bytes())
    });
    match r {
        Ok(()) => {
            tracing::info!(file = %dir.join(ADDR_FILE).display(), "socket published for cncctl")
        }
        Err(e) => tracing::warn!("cannot publish the socket in {}: {e}", dir.display()),
    }
}

/// Removes the publication at a clean stop if it still names `socket`.
pub fn unpublish(socket: &Path) {
    let file = runtime_dir().join(ADDR_FILE);
    if published().as_deref() == Some(absolute(socket).as_path()) {
        let _ = std::fs::remove_file(file);
    }
}

/// The published socket, if any.
pub fn published() -> Option<PathBuf> {
    let text = std::fs::read_to_string(runtime_dir().join(ADDR_FILE)).ok()?;
    text.trim().strip_prefix("unix:").map(PathBuf::from)
}
