//! Records CAN traffic in candump log format (`candump -l`, readable by `canplayer` and
//! `log2asc`): `(1700000000.123456) can0 181#0102030405060708`.
//!
//! The real-time side only pushes fixed-size records into a lock-free ring; a writer thread
//! formats and writes them, so recording never blocks a tick. When the ring is full, records
//! are dropped and counted (the writer notes the count in the log as a comment).

use std::fmt::Write as _;
use std::io::Write as _;
use std::path::Path;
use std::sync::Arc;
use std::sync::atomic::{AtomicU64, Ordering};
use std::thread::JoinHandle;
use std::time::{Duration, SystemTime, UNIX_EPOCH};

use crate::canopen::Frame;

#[derive(Clone, Copy)]
struct Record {
    micros: u64,
    frame: Frame,
}

/// The real-time side of a recording.
pub struct RecordTap {
    ring: rtrb::Producer<Record>,
    dropped: Arc<AtomicU64>,
}

impl RecordTap {
    /// Queues one frame with the current wall-clock time. Never blocks or allocates.
    pub fn record(&mut self, frame: &Frame) {
        let micros = SystemTime::now()
            .duration_since(UNIX_EPOCH)
            .map_or(0, |d| d.as_micros() as u64);
        if self
            .ring
            .push(Record {
                micros,
                frame: *frame,
            })
            .is_err()
        {
            self.dropped.fetch_add(1, Ordering::Relaxed);
        }
    }
}

/// Formats one candump log line (without newline) into `out`.
pub fn format_line(out: &mut String, micros: u64, iface: &str, frame: &Frame) {
    let _ = write!(
        out,
        "({}.{:06}) {} {:03X}#",
        micros / 1_000_000,
        micros % 1_000_000,
        iface,
        frame.id
    );
    for b in frame.payload() {
        let _ = write!(out, "{b:02X}");
    }
}

/// Why a CAN recording could not start.
#[derive(Debug, thiserror::Error)]
pub enum RecordError {
    #[error("cannot open CAN record file {}: {source}", path.display())]
    Open {
        path: std::path::PathBuf,
        #[source]
        source: std::io::Error,
    },
    #[error("cannot start the CAN recorder: {0}")]
    Thread(#[source] std::io::Error),
}

impl RecordError {
    /// Stable code (tests and logs match it; the message may improve).
    pub fn code(&self) -> &'static str {
        match self {
            RecordError::Open { .. } => "can_record_open",
            RecordError::Thread(_) => "can_record_thread",
        }
    }
}

/// Starts recording to `path` (appending). Returns the tap for the port and the writer thread,
/// which ends (after flushing) when the tap is dropped.
pub fn start(path: &Path, iface: &str) -> Result<(RecordTap, JoinHandle<()>), RecordError> {
    let file = std::fs::OpenOptions::new()
        .create(true)
        .append(true)
        .open(path)
        .map_err(|source| RecordError::Open {
            path: path.to_owned(),
            source,
        })?;
    // 4096 records = 1.3 s of traffic at 3 axes; the writer drains every 20 ms.
    let (producer, mut consumer) = rtrb::RingBuffer::<Record>::new(4096);
    let dropped = Arc::new(AtomicU64::new(0));
    let dropped_w = dropped.clone();
    let iface = iface.to_owned();
    let handle = std::thread::Builder::new()
        .name("candump".into())
        .spawn(move || {
            let mut out = std::io::BufWriter::new(file);
            let mut line = String::with_capacity(64);
            let mut reported = 0;
            loop {
                let abandoned = consumer.is_abandoned();
                while let Ok(r) = consumer.pop() {
                    line.clear();
                    format_line(&mut line, r.micros, &iface, &r.frame);
                    line.push('\n');
                    if out.write_all(line.as_bytes()).is_err() {
                        return;
                    }
                }
                let d = dropped_w.load(Ordering::Relaxed);
                if d != reported {
                    let _ = writeln!(
                        out,
                        "# {} frames not recorded (writer too slow)",
                        d - reported
                    );
                    reported = d;
                }
                let _ = out.flush();
                if abandoned {
                    return;
                }
                std::thread::sleep(Duration::from_millis(20));
            }
        })
        .map_err(RecordError::Thread)?;
    Ok((
        RecordTap {
            ring: producer,
            dropped,
        },
        handle,
    ))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn lines_match_candump() {
        let mut s = String::new();
        format_line(
            &mut s,
            1_700_000_000_012_345,
            "vcan0",
            &Frame::new(0x181, &[1, 0xAB]),
        );
        assert_eq!(s, "(1700000000.012345) vcan0 181#01AB");
        s.clear();
        format_line(&mut s, 5, "can0", &Frame::new(0x80, &[]));
        assert_eq!(s, "(0.000005) can0 080#");
    }

    #[test]
    fn recorder_writes_every_frame() {
        let dir = std::env::temp_dir().join(format!("candump-test-{}", std::process::id()));
        let _ = std::fs::remove_file(&dir);
        let (mut tap, handle) = start(&dir, "vcan0").unwrap();
        for i in 0..100u16 {
            tap.record(&Frame::new(0x200 + (i % 3), &i.to_le_bytes()));
        }
        drop(tap);
        handle.join().unwrap();
        let text = std::fs::read_to_string(&dir).unwrap();
        let _ = std::fs::remove_file(&dir);
        let lines: Vec<&str> = text.lines().collect();
        assert_eq!(lines.len(), 100);
        assert!(lines[99].ends_with(" vcan0 200#6300"), "{}", lines[99]);
    }
}
