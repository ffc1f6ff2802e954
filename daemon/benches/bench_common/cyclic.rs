//! cyclictest (rt-tests) beside a bench: this machine's own timer floor, to read the RT
//! thread's tick lateness against. Each bench uses a part.
#![allow(dead_code)]

use std::process::{Command, Stdio};

/// The RT thread's period the benches run at, µs.
pub const PERIOD_US: u64 = 4000;

pub struct Cyclic {
    pub p50_us: u64,
    pub p99_us: u64,
    pub max_us: u64,
    pub overruns: u64,
    pub samples: u64,
}

/// Parses `cyclictest -h` output: one `bucket count` line per µs (up to 100 ms), then
/// `# Max Latencies`.
pub fn parse_cyclictest(out: &str) -> Option<Cyclic> {
    let mut hist: Vec<(u64, u64)> = Vec::new();
    let mut max_us = None;
    let mut overflows = 0;
    for line in out.lines() {
        if let Some(r) = line.strip_prefix("# Max Latencies:") {
            max_us = r.split_whitespace().next().and_then(|v| v.parse().ok());
        } else if let Some(r) = line.strip_prefix("# Histogram Overflows:") {
            overflows = r
                .split_whitespace()
                .next()
                .and_then(|v| v.parse().ok())
                .unwrap_or(0);
        } else if !line.starts_with('#') {
            let mut it = line.split_whitespace();
            if let (Some(b), Some(c)) = (it.next(), it.next())
                && let (Ok(b), Ok(c)) = (b.parse::<u64>(), c.parse::<u64>())
            {
                hist.push((b, c));
            }
        }
    }
    let samples: u64 = hist.iter().map(|h| h.1).sum::<u64>() + overflows;
    if samples == 0 {
        return None;
    }
    let pct = |p: f64| {
        let target = (samples as f64 * p).ceil() as u64;
        let mut acc = 0;
        for (b, c) in &hist {
            acc += c;
            if acc >= target {
                return *b;
            }
        }
        max_us.unwrap_or(0)
    };
    // Missed deadlines, counted as the RT thread counts them: a wake-up L µs late missed
    // floor(L / period) deadlines. Overflows (beyond the histogram) count as one each.
    let overruns = hist.iter().map(|(b, c)| b / PERIOD_US * c).sum::<u64>() + overflows;
    Some(Cyclic {
        p50_us: pct(0.50),
        p99_us: pct(0.99),
        max_us: max_us.unwrap_or(0),
        overruns,
        samples,
    })
}

pub fn ensure_cyclictest() -> bool {
    if Command::new("cyclictest")
        .arg("--help")
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .status()
        .is_ok()
    {
        return true;
    }
    eprintln!("cyclictest not found: trying `apt-get install -y rt-tests`");
    let ok = Command::new("apt-get")
        .args(["install", "-y", "-q", "rt-tests"])
        .status()
        .is_ok_and(|s| s.success());
    if !ok {
        eprintln!(
            "could not install rt-tests; install it with `sudo apt-get install rt-tests` \
             (Debian/Ubuntu) and run the bench again. Continuing without the comparison."
        );
    }
    ok
}

pub fn percentile(v: &mut [f64], p: f64) -> f64 {
    if v.is_empty() {
        return 0.0;
    }
    v.sort_by(|a, b| a.total_cmp(b));
    v[((v.len() - 1) as f64 * p).round() as usize]
}

/// Starts `cyclictest` for `secs` seconds at the RT thread's period (4 ms, clock_nanosleep,
/// SCHED_FIFO 80, mlockall, one thread, a histogram to 100 ms), installing rt-tests if it can.
pub fn spawn_cyclictest(secs: u64) -> Option<std::process::Child> {
    if !ensure_cyclictest() {
        return None;
    }
    Command::new("cyclictest")
        .args([
            "-m",
            "-q",
            "-p80",
            "-t1",
            "-i4000",
            "-h100000",
            &format!("-D{secs}s"),
        ])
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .ok()
}

/// Waits for a cyclictest started by [`spawn_cyclictest`] and reads its histogram.
pub fn finish_cyclictest(c: Option<std::process::Child>) -> Option<Cyclic> {
    let out = c?.wait_with_output().ok()?;
    parse_cyclictest(&String::from_utf8_lossy(&out.stdout))
}
