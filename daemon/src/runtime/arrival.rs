//! An upload read while it is being written (issue #49): its validation runs as its bytes
//! arrive, so a load ends about when its last chunk arrives, not a whole validation after it
//! (a million blocks: 0.13 s of upload on a Unix socket, far more over a network).
//!
//! The writer ([`crate::runtime::library::Upload`]) reports every chunk it has written
//! ([`Arrival::wrote`]) and how the upload ended ([`Arrival::end`]); an [`ArrivingReader`]
//! reads the file through its own position (`pread`) up to the bytes written and waits for
//! more until the upload is complete. An abandoned upload (a failed part, a closed stream, an
//! idle session dropped) ends every read with an error, so its validation ends at once.

use std::fs::File;
use std::io::{self, Read, Seek, SeekFrom};
use std::os::unix::fs::FileExt;
use std::sync::{Arc, Condvar, Mutex};

/// How an upload ended.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum End {
    /// Every byte is written: a read past them is the end of the text.
    Complete,
    /// The upload will not complete (and will not be stored).
    Abandoned,
}

#[derive(Debug, Default)]
struct Arrived {
    bytes: u64,
    end: Option<End>,
}

/// What has arrived of one upload, shared by its writer and its readers.
#[derive(Debug, Default)]
pub struct Arrival {
    arrived: Mutex<Arrived>,
    more: Condvar,
}

impl Arrival {
    pub fn new() -> Arc<Arrival> {
        Arc::new(Arrival::default())
    }

    /// The first `bytes` bytes of the file are written (readable through another handle).
    pub fn wrote(&self, bytes: u64) {
        self.arrived.lock().unwrap().bytes = bytes;
        self.more.notify_all();
    }

    /// The upload ended (the first end holds: an upload completed, then dropped once stored,
    /// stays complete).
    pub fn end(&self, end: End) {
        let mut a = self.arrived.lock().unwrap();
        a.end.get_or_insert(end);
        self.more.notify_all();
    }

    /// Bytes written so far.
    pub fn bytes(&self) -> u64 {
        self.arrived.lock().unwrap().bytes
    }

    /// Waits until a byte at `pos` has arrived or the upload ended: how many bytes from `pos`
    /// may be read (0: the end of a complete upload).
    fn readable_from(&self, pos: u64) -> io::Result<u64> {
        let mut a = self.arrived.lock().unwrap();
        loop {
            match a.end {
                Some(End::Abandoned) => return Err(abandoned()),
                _ if a.bytes > pos => return Ok(a.bytes - pos),
                Some(End::Complete) => return Ok(0),
                None => a = self.more.wait(a).unwrap(),
            }
        }
    }

    /// The size of the complete upload (waits for its end).
    fn total(&self) -> io::Result<u64> {
        let mut a = self.arrived.lock().unwrap();
        loop {
            match a.end {
                Some(End::Abandoned) => return Err(abandoned()),
                Some(End::Complete) => return Ok(a.bytes),
                None => a = self.more.wait(a).unwrap(),
            }
        }
    }
}

fn abandoned() -> io::Error {
    io::Error::new(io::ErrorKind::UnexpectedEof, "the upload was abandoned")
}

/// Reads an upload's file as it arrives, from a position of its own.
pub struct ArrivingReader {
    file: Arc<File>,
    arrival: Arc<Arrival>,
    pos: u64,
}

impl ArrivingReader {
    /// Reads `file` (the upload's temporary file, opened for reading) as `arrival` says it is
    /// written.
    pub fn new(file: Arc<File>, arrival: Arc<Arrival>) -> ArrivingReader {
        ArrivingReader {
            file,
            arrival,
            pos: 0,
        }
    }
}

impl Read for ArrivingReader {
    fn read(&mut self, buf: &mut [u8]) -> io::Result<usize> {
        if buf.is_empty() {
            return Ok(0);
        }
        let ready = self.arrival.readable_from(self.pos)?;
        let n = buf.len().min(usize::try_from(ready).unwrap_or(usize::MAX));
        let got = self.file.read_at(&mut buf[..n], self.pos)?;
        self.pos += got as u64;
        Ok(got)
    }
}

/// Going back is what the ISO dialect's loops and calls do; from the end waits for the end.
impl Seek for ArrivingReader {
    fn seek(&mut self, to: SeekFrom) -> io::Result<u64> {
        let bad = || io::Error::new(io::ErrorKind::InvalidInput, "seek before the start");
        self.pos = match to {
            SeekFrom::Start(p) => p,
            SeekFrom::Current(d) => self.pos.checked_add_signed(d).ok_or_else(bad)?,
            SeekFrom::End(d) => self.arrival.total()?.saturating_add_signed(d),
        };
        Ok(self.pos)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::io::Write;

    fn file_pair() -> (File, Arc<File>) {
        let dir = std::env::temp_dir().join(format!("arrival-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join(format!("{:?}.tmp", std::thread::current().id()));
        let w = File::create(&path).unwrap();
        let r = Arc::new(File::open(&path).unwrap());
        std::fs::remove_file(&path).unwrap();
        (w, r)
    }

    #[test]
    fn a_reader_waits_for_what_arrives_and_ends_with_the_upload() {
        let (mut w, r) = file_pair();
        let arrival = Arrival::new();
        let mut reader = ArrivingReader::new(r, arrival.clone());
        let read_all = std::thread::spawn(move || {
            let mut text = String::new();
            reader.read_to_string(&mut text).map(|_| text)
        });
        for part in ["N1 G1 X1\n", "N2 X2\n", "N3 X3"] {
            w.write_all(part.as_bytes()).unwrap();
            arrival.wrote(arrival.bytes() + part.len() as u64);
            std::thread::sleep(std::time::Duration::from_millis(5));
        }
        arrival.end(End::Complete);
        assert_eq!(read_all.join().unwrap().unwrap(), "N1 G1 X1\nN2 X2\nN3 X3");
    }

    #[test]
    fn an_abandoned_upload_ends_its_reads_with_an_error() {
        let (mut w, r) = file_pair();
        let arrival = Arrival::new();
        let mut reader = ArrivingReader::new(r, arrival.clone());
        w.write_all(b"N1 G1 X1\n").unwrap();
        arrival.wrote(9);
        let mut buf = [0u8; 64];
        assert_eq!(reader.read(&mut buf).unwrap(), 9);
        let waiting = std::thread::spawn(move || reader.read(&mut buf).map_err(|e| e.kind()));
        std::thread::sleep(std::time::Duration::from_millis(5));
        arrival.end(End::Abandoned);
        arrival.end(End::Complete);
        assert_eq!(
            waiting.join().unwrap(),
            Err(io::ErrorKind::UnexpectedEof),
            "the first end holds"
        );
    }
}
