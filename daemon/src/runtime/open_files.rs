//! The open-file limit of the daemon (issue #50, "floods stay held"): every connection to the
//! API, the HMI or the MTConnect agent holds a descriptor until it ends or its request head
//! times out (30 s). With the usual soft limit of 1024, a few hundred clients that connect and
//! wait would use them up, and the operator's own `cncctl` (the Unix socket) could not connect
//! until they timed out. Raised at start-up, before any listener exists.

/// Descriptors cncd asks for: room for thousands of idle connections (about 30 KB each)
/// with the bus, the files and the operator's socket left over.
pub const WANTED: u64 = 65_536;

/// Below this the daemon warns at start: a few thousand idle connections would take them all.
pub const LOW: u64 = 8_192;

/// Raises the soft limit toward [`WANTED`], as far as the hard limit allows (an unprivileged
/// process may). Returns the soft limit before and after; `None` when it cannot be read.
pub fn raise() -> Option<(u64, u64)> {
    let mut lim = libc::rlimit {
        rlim_cur: 0,
        rlim_max: 0,
    };
    // SAFETY: plain syscalls on a local struct.
    if unsafe { libc::getrlimit(libc::RLIMIT_NOFILE, &mut lim) } != 0 {
        return None;
    }
    let before = lim.rlim_cur;
    let want = WANTED.min(lim.rlim_max);
    if want > before {
        lim.rlim_cur = want;
        // SAFETY: as above.
        if unsafe { libc::setrlimit(libc::RLIMIT_NOFILE, &lim) } != 0 {
            return Some((before, before));
        }
    }
    Some((before, lim.rlim_cur.max(before)))
}

#[cfg(test)]
mod tests {
    #[test]
    fn the_soft_limit_only_rises() {
        let (before, after) = super::raise().expect("getrlimit");
        assert!(after >= before);
        assert_eq!(super::raise().unwrap().0, after);
    }
}
