//! Clocks for the real-time loop: the monotonic clock of the machine, and a simulated clock for
//! the single-threaded harness of the tests ([`super::harness`]): seeded jitter, late ticks and
//! missed deadlines, hours of machining in seconds, deterministically.

use kernel::units::TS_NS;

/// Time source of the tick loop, in nanoseconds of its own time base.
pub trait Clock: Send {
    fn now_ns(&self) -> u64;
    /// Sleeps until the absolute time `deadline_ns` (returns at once if it has passed).
    fn sleep_until_ns(&mut self, deadline_ns: u64);
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

/// A simulated clock for the single-threaded harness: the tick wakes at its deadline plus a
/// seeded random jitter, now and then late by one or more whole periods (missed deadlines),
/// and exactly as late as the test says at the ticks it names. Same seed, same wake-ups: a run
/// replays bit for bit. No wall clock anywhere.
#[derive(Clone, Debug)]
pub struct SimClock {
    /// SplitMix64 state.
    state: u64,
    /// Wake-ups are late by up to this much (uniform), ns.
    pub jitter_ns: u64,
    /// One wake-up in this many is late by one to `late_max_periods` whole periods (0: never).
    pub late_one_in: u64,
    pub late_max_periods: u64,
    /// The period late wake-ups are late by whole multiples of, ns (the tick's period; the
    /// harness sets the configuration's bus period).
    pub period_ns: u64,
    /// Exact lateness for given wake-ups, counted from 0: (wake-up, lateness ns), any order.
    pub forced: Vec<(u64, u64)>,
    wakeups: u64,
    now_ns: u64,
}

impl SimClock {
    /// Every wake-up exactly on its deadline.
    pub fn exact() -> SimClock {
        SimClock::seeded(0, 0, 0)
    }

    /// Jitter up to `jitter_ns`, and one wake-up in `late_one_in` late by 1..=3 periods.
    pub fn seeded(seed: u64, jitter_ns: u64, late_one_in: u64) -> SimClock {
        SimClock {
            state: seed,
            jitter_ns,
            late_one_in,
            late_max_periods: 3,
            period_ns: TS_NS,
            forced: Vec::new(),
            wakeups: 0,
            now_ns: 0,
        }
    }

    /// The clock's time now, ns.
    pub fn now_ns(&self) -> u64 {
        self.now_ns
    }

    /// Wake-ups so far.
    pub fn wakeups(&self) -> u64 {
        self.wakeups
    }

    /// Sleeps until `deadline_ns` and returns the time the sleeper wakes (never before it).
    pub fn wake(&mut self, deadline_ns: u64) -> u64 {
        let lateness = self.lateness_ns();
        self.wakeups += 1;
        self.now_ns = self.now_ns.max(deadline_ns + lateness);
        self.now_ns
    }

    fn lateness_ns(&mut self) -> u64 {
        if let Some(&(_, ns)) = self.forced.iter().find(|(w, _)| *w == self.wakeups) {
            return ns;
        }
        let mut late = 0;
        if self.jitter_ns > 0 {
            late = self.next() % (self.jitter_ns + 1);
        }
        if self.late_one_in > 0 && self.next().is_multiple_of(self.late_one_in) {
            late += (1 + self.next() % self.late_max_periods.max(1)) * self.period_ns;
        }
        late
    }

    /// SplitMix64: small, fast, and the same on every platform.
    fn next(&mut self) -> u64 {
        self.state = self.state.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.state;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
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
    fn sim_clock_is_seeded_never_early_and_forced_where_told() {
        let run = |seed| {
            let mut c = SimClock::seeded(seed, 300_000, 10);
            c.forced.push((0, 2 * TS_NS + 1));
            (1..=1000u64)
                .map(|k| {
                    let deadline = k * TS_NS;
                    let now = c.wake(deadline);
                    assert!(now >= deadline);
                    now
                })
                .collect::<Vec<_>>()
        };
        let a = run(7);
        assert_eq!(a, run(7));
        assert_ne!(a, run(8));
        assert_eq!(a[0], TS_NS + 2 * TS_NS + 1);
        let late = (0..1000)
            .filter(|&i| a[i] - (i as u64 + 1) * TS_NS >= TS_NS)
            .count();
        assert!((50..=200).contains(&late), "{late} late wake-ups of 1000");
    }
}
