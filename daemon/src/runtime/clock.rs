//! Clocks for the real-time loop: the monotonic clock of the machine, and a virtual clock that
//! lets tests run hours of machining in seconds, deterministically.

/// Time source of the tick loop, in nanoseconds of its own time base.
pub trait Clock: Send {
    fn now_ns(&self) -> u64;
    /// Sleeps until the absolute time `deadline_ns` (returns at once if it has passed).
    fn sleep_until_ns(&mut self, deadline_ns: u64);
    /// Whether time is virtual (no real waiting happens).
    fn is_virtual(&self) -> bool {
        false
    }
}

/// `CLOCK_MONOTONIC` with absolute-deadline sleeps (`clock_nanosleep(TIMER_ABSTIME)`), so the
/// loop stays on its deadline grid and does not drift by the time each tick takes.
#[derive(Default)]
pub struct MonotonicClock;

impl Clock for MonotonicClock {
    fn now_ns(&self) -> u64 {
        let mut ts = libc::timespec {
            tv_sec: 0,
            tv_nsec: 0,
        };
        // SAFETY: valid pointer to a timespec; CLOCK_MONOTONIC always exists on Linux.
        unsafe { libc::clock_gettime(libc::CLOCK_MONOTONIC, &mut ts) };
        ts.tv_sec as u64 * 1_000_000_000 + ts.tv_nsec as u64
    }

    fn sleep_until_ns(&mut self, deadline_ns: u64) {
        let ts = libc::timespec {
            tv_sec: (deadline_ns / 1_000_000_000) as libc::time_t,
            tv_nsec: (deadline_ns % 1_000_000_000) as libc::c_long,
        };
        loop {
            // SAFETY: valid timespec; a null remainder is allowed with TIMER_ABSTIME.
            let rc = unsafe {
                libc::clock_nanosleep(
                    libc::CLOCK_MONOTONIC,
                    libc::TIMER_ABSTIME,
                    &ts,
                    std::ptr::null_mut(),
                )
            };
            // EINTR: a signal woke us early; the deadline is absolute, so just sleep again.
            if rc != libc::EINTR {
                break;
            }
        }
    }
}

/// Virtual time: `sleep_until_ns` jumps to the deadline at once. Every tick is exactly on time.
#[derive(Default)]
pub struct VirtualClock {
    now_ns: u64,
}

impl Clock for VirtualClock {
    fn now_ns(&self) -> u64 {
        self.now_ns
    }

    fn sleep_until_ns(&mut self, deadline_ns: u64) {
        self.now_ns = self.now_ns.max(deadline_ns);
    }

    fn is_virtual(&self) -> bool {
        true
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn monotonic_sleep_reaches_deadline() {
        let mut c = MonotonicClock;
        let t0 = c.now_ns();
        c.sleep_until_ns(t0 + 2_000_000);
        assert!(c.now_ns() >= t0 + 2_000_000);
    }

    #[test]
    fn virtual_clock_jumps() {
        let mut c = VirtualClock::default();
        c.sleep_until_ns(3_600_000_000_000);
        assert_eq!(c.now_ns(), 3_600_000_000_000);
        c.sleep_until_ns(5);
        assert_eq!(c.now_ns(), 3_600_000_000_000);
    }
}
