//! Which protocol version a link needs, and how a unit of an older version is told from a
//! silent one. Homing needs version 3, digital I/O version 4; otherwise the link speaks the
//! oldest version that carries its records (1, or 2 with a spindle) and needs nothing.
//!
//! Until a reply in the needed version arrives, every [`PROBE_EVERY_TICKS`]th tick without a
//! reply the request goes out in an older version with every controlword 0: a probe. A unit
//! that answers [`PROBE_ANSWERS`] probes and never the needed version is old: refused.

use crate::FaultReason;

/// Ticks of silence between probes.
pub const PROBE_EVERY_TICKS: u32 = 3;
/// Probes answered by a unit that never answered the needed version: it is an old unit.
pub const PROBE_ANSWERS: u32 = 3;

/// The version check of one link.
#[derive(Clone, Copy, Debug, Default)]
pub struct VersionCheck {
    /// The version the configuration needs (3 homing, 4 I/O); 0: any.
    needed: u8,
    /// The version the link speaks without homing and I/O (1, or 2 with a spindle).
    plain: u8,
    /// Version 3 is worth a probe: homing is configured and version 4 needed, so a unit of
    /// version 3 is named as one (it answers version 3 with the homing record).
    probe_v3: bool,
    /// A reply in the needed version arrived.
    seen: bool,
    /// The version of the last request if it was a probe.
    probing: Option<u8>,
    probes_sent: u32,
    answers: u32,
    /// The newest version a probe was answered in.
    best: u8,
}

impl VersionCheck {
    pub fn new(spindle: bool, homing: bool, io: bool) -> VersionCheck {
        let needed = match (io, homing) {
            (true, _) => 4,
            (false, true) => 3,
            (false, false) => 0,
        };
        VersionCheck {
            needed,
            plain: 1 + u8::from(spindle),
            probe_v3: io && homing,
            ..VersionCheck::default()
        }
    }

    /// The same check from the start (the unit may have been swapped).
    pub fn restart(&mut self) {
        *self = VersionCheck {
            needed: self.needed,
            plain: self.plain,
            probe_v3: self.probe_v3,
            ..VersionCheck::default()
        };
    }

    /// The version the next request goes out in if it is a probe (`missing`: ticks without a
    /// reply so far), `None` for a request in the link's own version. Probes alternate
    /// between version 3 (when worth it) and the plain version, so an old unit of either kind
    /// answers.
    pub fn next_request(&mut self, missing: u32) -> Option<u8> {
        let due = self.needed > 0
            && !self.seen
            && missing > 0
            && missing.is_multiple_of(PROBE_EVERY_TICKS);
        self.probing = due.then(|| {
            self.probes_sent += 1;
            if self.probe_v3 && self.probes_sent % 2 == 1 {
                3
            } else {
                self.plain
            }
        });
        self.probing
    }

    /// Whether a reply of `version` is older than the link needs (a probe's answer, or an
    /// old unit's answer to nothing it was asked).
    pub fn is_older(&self, version: u8) -> bool {
        version < self.needed
    }

    /// Whether the last request was a probe.
    pub fn probing(&self) -> bool {
        self.probing.is_some()
    }

    /// A reply in the needed version.
    pub fn confirm(&mut self) {
        self.seen = true;
    }

    /// A probe answered in `version`: the refusal once enough came and none in the needed
    /// version.
    pub fn probe_answered(&mut self, version: u8) -> Option<FaultReason> {
        self.answers += 1;
        self.best = self.best.max(version);
        (!self.seen && self.answers >= PROBE_ANSWERS).then_some(FaultReason::ProtocolVersion {
            drive: self.best,
            needed: self.needed,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn needs_and_probes() {
        let mut plain = VersionCheck::new(true, false, false);
        assert!(
            (1..=9).all(|m| plain.next_request(m).is_none()),
            "needs nothing"
        );
        let mut homing = VersionCheck::new(true, true, false);
        assert_eq!(homing.next_request(3), Some(2));
        assert!(homing.is_older(2) && !homing.is_older(3));
        let mut io = VersionCheck::new(false, true, true);
        let probes: Vec<_> = [3, 6, 3, 6].map(|m| io.next_request(m)).into();
        assert_eq!(probes, [Some(3), Some(1), Some(3), Some(1)]);
        assert_eq!(io.next_request(4), None);
        assert!(!io.probing());
        assert_eq!(io.probe_answered(1), None);
        assert_eq!(io.probe_answered(3), None);
        assert_eq!(
            io.probe_answered(1),
            Some(FaultReason::ProtocolVersion {
                drive: 3,
                needed: 4
            })
        );
        io.restart();
        io.confirm();
        assert_eq!(
            io.next_request(3),
            None,
            "a unit of version 4 is not probed"
        );
    }
}
