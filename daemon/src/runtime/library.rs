//! The program library on disk, and programs read from files (issue #19).
//!
//! - Every stored program is a file in `storage.programs_dir` (name: a hash of the program's
//!   name, so any printable name is safe on disk) beside a small `.meta` file (name, blocks,
//!   validation verdict). Both are written atomically (temporary file, fsync, rename): a crash
//!   leaves the old program or the new one. The library survives restarts; its size is bounded
//!   by `storage.programs_max_bytes`. The selected program's name is kept in `.selected`.
//! - A program runs from its file: [`ProgramText::File`] holds the open file of the version
//!   that was validated (a later upload under the same name replaces the directory entry, not
//!   the open file), and [`FileLines`] feeds its lines through a fixed buffer into the one
//!   pipeline (`kernel::pipeline::run_lines`), so validation and run see what a string would
//!   give and memory stays bounded by the look-ahead whatever the program's size.
//!
//! The calls block on disk IO: from async code run them in `spawn_blocking`.

use std::collections::BTreeMap;
use std::fs::{self, File, OpenOptions};
use std::io::{self, BufRead, BufReader, Read, Write};
use std::os::unix::fs::FileExt;
use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex};
use std::time::{SystemTime, UNIX_EPOCH};

use kernel::machine::MachineSetup;
use kernel::pipeline::{self, Observer, Options, Summary, Validation};
use kernel::program::Lines;
use kernel::program::encoding::TextEncoding;
use kernel::{DiagCode, Diagnostic};
use sha2::{Digest, Sha256};

use super::storage::write_atomic;

/// Read buffer of a program streamed from its file.
const READ_BUFFER_BYTES: usize = 256 * 1024;

/// The text of a program: in memory (MDI, small texts) or an open file (library programs).
#[derive(Clone)]
pub enum ProgramText {
    Memory(Arc<str>),
    File(Arc<File>),
}

impl ProgramText {
    /// Streams the text through the one pipeline (`kernel::pipeline::run`) into `obs`; a file
    /// is read line by line through a fixed buffer.
    pub fn run(&self, setup: &MachineSetup, opts: Options, obs: &mut impl Observer) -> Summary {
        match self {
            ProgramText::Memory(t) => pipeline::run(t, setup, opts, obs),
            ProgramText::File(f) => pipeline::run_lines(
                FileLines::open(f).with_encoding(setup.program().encoding),
                setup,
                opts,
                obs,
            ),
        }
    }

    /// The pipeline's verdict on the text (`kernel::pipeline::validate_into`), `inner` seeing
    /// the same pass.
    pub fn validate_into(
        &self,
        setup: &MachineSetup,
        opts: Options,
        inner: &mut impl Observer,
    ) -> Validation {
        match self {
            ProgramText::Memory(t) => pipeline::validate_into(t, setup, opts, inner),
            ProgramText::File(f) => {
                let lines = FileLines::open(f).with_encoding(setup.program().encoding);
                pipeline::validate_lines_into(lines, setup, opts, inner)
            }
        }
    }

    /// The whole text in memory (previews, single-block runs): costs memory in proportion to
    /// the program.
    /// A file is decoded with `encoding` (`[program] encoding`).
    pub fn read_all(&self, encoding: TextEncoding) -> io::Result<Arc<str>> {
        match self {
            ProgramText::Memory(t) => Ok(t.clone()),
            ProgramText::File(f) => {
                let mut bytes = Vec::new();
                PosReader::new(f.clone()).read_to_end(&mut bytes)?;
                let text = encoding.decode(&bytes).ok_or_else(|| {
                    io::Error::new(io::ErrorKind::InvalidData, "the program is not UTF-8")
                })?;
                Ok(text.into())
            }
        }
    }

    /// Size in bytes.
    pub fn len(&self) -> u64 {
        match self {
            ProgramText::Memory(t) => t.len() as u64,
            ProgramText::File(f) => f.metadata().map(|m| m.len()).unwrap_or(0),
        }
    }

    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }
}

/// Reads a shared open file from its own position (`pread`), so a validation and a run can
/// read the same file at once.
pub struct PosReader {
    file: Arc<File>,
    pos: u64,
}

impl PosReader {
    pub fn new(file: Arc<File>) -> Self {
        PosReader { file, pos: 0 }
    }
}

impl Read for PosReader {
    fn read(&mut self, buf: &mut [u8]) -> io::Result<usize> {
        let n = self.file.read_at(buf, self.pos)?;
        self.pos += n as u64;
        Ok(n)
    }
}

/// The lines of a program read from `R` for the kernel's stream (`kernel::program::Lines`):
/// the same lines as from a string. A line that is not UTF-8 is an error located by line,
/// column and byte offset; a read error ends the text with an error.
pub struct FileLines<R> {
    reader: R,
    line: Vec<u8>,
    /// Code page of the file (`[program] encoding`), and a line decoded from it.
    encoding: TextEncoding,
    decoded: String,
    /// Byte offset of the next line in the file.
    offset: u64,
    done: bool,
}

impl FileLines<BufReader<PosReader>> {
    /// An open program file from its start.
    pub fn open(file: &Arc<File>) -> Self {
        FileLines::new(BufReader::with_capacity(
            READ_BUFFER_BYTES,
            PosReader::new(file.clone()),
        ))
    }
}

impl<R: BufRead> FileLines<R> {
    pub fn new(reader: R) -> Self {
        FileLines {
            reader,
            line: Vec::with_capacity(256),
            encoding: TextEncoding::Utf8,
            decoded: String::new(),
            offset: 0,
            done: false,
        }
    }
}

impl<R> FileLines<R> {
    /// Lines decoded from `encoding` (UTF-8 without this).
    pub fn with_encoding(mut self, encoding: TextEncoding) -> Self {
        self.encoding = encoding;
        self
    }
}

impl<R: BufRead> Lines for FileLines<R> {
    fn next_line(&mut self, line_no: u32) -> Option<Result<&str, Diagnostic>> {
        if self.done {
            return None;
        }
        self.line.clear();
        if let Err(e) = self.reader.read_until(b'\n', &mut self.line) {
            self.done = true;
            let msg = format!("cannot read the program file: {e}");
            return Some(Err(Diagnostic::error(
                DiagCode::ProgramUnreadable,
                None,
                line_no,
                0,
                msg,
            )));
        }
        if self.line.last() == Some(&b'\n') {
            self.line.pop();
        } else {
            self.done = true;
        }
        let start = self.offset;
        self.offset += self.line.len() as u64 + 1;
        if self.encoding != TextEncoding::Utf8 && !self.line.is_ascii() {
            // (A single-byte page decodes every byte.)
            self.decoded = self
                .encoding
                .decode(&self.line)
                .unwrap_or_default()
                .into_owned();
            return Some(Ok(&self.decoded));
        }
        match std::str::from_utf8(&self.line) {
            Ok(t) => Some(Ok(t)),
            Err(_) => {
                let at = proto::codec::locate_bad_utf8(&self.line).expect("not UTF-8");
                Some(Err(Diagnostic::error(
                    DiagCode::TextNotUtf8,
                    None,
                    line_no,
                    at.column,
                    format!(
                        "the text is not UTF-8 here (byte offset {} of the file); save the \
                         program as UTF-8",
                        start + at.offset as u64
                    ),
                )))
            }
        }
    }
}

/// What the library knows of one stored program.
#[derive(Clone, Debug, PartialEq)]
pub struct Entry {
    pub name: String,
    pub size_bytes: u64,
    pub blocks: u32,
    pub modified_unix_ms: u64,
    pub verdict: Verdict,
    /// The text's revision: the first 16 hex digits of its SHA-256 (issue #31: the listing
    /// says which text is stored, the status which one is selected). Empty for a program
    /// stored before revisions were kept.
    pub revision: String,
}

/// The outcome of the last validation of a stored program (at upload, at each selection).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Verdict {
    pub valid: bool,
    pub errors: u32,
    pub warnings: u32,
    /// The first error, as a machinist reads it ("" when valid).
    pub first_error: String,
}

impl Verdict {
    pub fn of(diagnostics: &[Diagnostic]) -> Verdict {
        let errors = diagnostics.iter().filter(|d| d.is_error()).count() as u32;
        Verdict {
            valid: errors == 0,
            errors,
            warnings: diagnostics
                .iter()
                .filter(|d| d.severity == kernel::Severity::Warning)
                .count() as u32,
            first_error: diagnostics
                .iter()
                .find(|d| d.is_error())
                .map(ToString::to_string)
                .unwrap_or_default(),
        }
    }
}

/// Why a library operation was refused. Nothing changed.
#[derive(Debug, thiserror::Error)]
pub enum LibraryError {
    #[error("no stored program is called {0:?}")]
    NotFound(String),
    #[error("a program called {0:?} is stored already")]
    Exists(String),
    #[error(
        "the program library would hold {would} bytes, more than storage.programs_max_bytes \
         ({max}); delete programs first"
    )]
    Full { would: u64, max: u64 },
    #[error("{0}")]
    Io(#[from] io::Error),
}

/// The stored programs: files in one directory, an index in memory.
pub struct Library {
    dir: PathBuf,
    max_bytes: u64,
    index: Mutex<BTreeMap<String, Entry>>,
    /// Serialises writers (upload commits, renames, deletes) with each other.
    writer: Mutex<()>,
}

fn now_ms() -> u64 {
    SystemTime::now()
        .duration_since(UNIX_EPOCH)
        .map_or(0, |d| d.as_millis() as u64)
}

fn stem(name: &str) -> String {
    let d = Sha256::digest(name.as_bytes());
    d.iter().take(16).map(|b| format!("{b:02x}")).collect()
}

impl Library {
    /// Opens (creates) the library directory and reads the index of what is stored. Files
    /// without a readable `.meta` (an interrupted upload) are ignored and removed.
    pub fn open(dir: &Path, max_bytes: u64) -> io::Result<Library> {
        fs::create_dir_all(dir)?;
        let mut index = BTreeMap::new();
        for e in fs::read_dir(dir)? {
            let p = e?.path();
            let is_tmp = p
                .file_name()
                .is_some_and(|n| n.to_string_lossy().starts_with(".upload-"));
            if is_tmp {
                let _ = fs::remove_file(&p);
                continue;
            }
            if p.extension().is_some_and(|x| x == "meta")
                && let Some(entry) = read_meta(&p)
            {
                index.insert(entry.name.clone(), entry);
            }
        }
        Ok(Library {
            dir: dir.to_owned(),
            max_bytes,
            index: Mutex::new(index),
            writer: Mutex::new(()),
        })
    }

    fn program_path(&self, name: &str) -> PathBuf {
        self.dir.join(format!("{}.nc", stem(name)))
    }

    fn meta_path(&self, name: &str) -> PathBuf {
        self.dir.join(format!("{}.meta", stem(name)))
    }

    pub fn list(&self) -> Vec<Entry> {
        self.index.lock().unwrap().values().cloned().collect()
    }

    pub fn used_bytes(&self) -> u64 {
        self.index
            .lock()
            .unwrap()
            .values()
            .map(|e| e.size_bytes)
            .sum()
    }

    pub fn max_bytes(&self) -> u64 {
        self.max_bytes
    }

    pub fn entry(&self, name: &str) -> Option<Entry> {
        self.index.lock().unwrap().get(name).cloned()
    }

    /// The stored program opened for reading (this version stays readable whatever happens
    /// to the name later).
    pub fn open_program(&self, name: &str) -> Result<(Arc<File>, Entry), LibraryError> {
        let entry = self
            .entry(name)
            .ok_or_else(|| LibraryError::NotFound(name.into()))?;
        Ok((Arc::new(File::open(self.program_path(name))?), entry))
    }

    /// Starts an upload of `name`: a temporary file in the library directory. The space the
    /// upload may use is checked while it is written ([`Upload::write`]).
    pub fn begin_upload(&self, name: &str) -> Result<Upload, LibraryError> {
        static N: std::sync::atomic::AtomicU64 = std::sync::atomic::AtomicU64::new(0);
        let n = N.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
        let tmp = self
            .dir
            .join(format!(".upload-{}-{n}.tmp", std::process::id()));
        let file = OpenOptions::new().write(true).create_new(true).open(&tmp)?;
        let replaced = self.entry(name).map_or(0, |e| e.size_bytes);
        Ok(Upload {
            tmp,
            file: Some(file),
            written: 0,
            allowed: self
                .max_bytes
                .saturating_sub(self.used_bytes().saturating_sub(replaced)),
            max: self.max_bytes,
            hash: Sha256::new(),
        })
    }

    /// Stores an upload under `name` (replacing a program of that name) with its verdict.
    /// Returns the entry and the stored file, opened.
    pub fn commit(
        &self,
        name: &str,
        mut up: Upload,
        blocks: u32,
        verdict: Verdict,
    ) -> Result<(Entry, Arc<File>), LibraryError> {
        let _w = self.writer.lock().unwrap();
        let file = up.file.take().expect("upload not committed twice");
        file.sync_all()?;
        drop(file);
        let replaced = self.entry(name).map_or(0, |e| e.size_bytes);
        let would = self.used_bytes() - replaced + up.written;
        if would > self.max_bytes {
            return Err(LibraryError::Full {
                would,
                max: self.max_bytes,
            });
        }
        let entry = Entry {
            name: name.into(),
            size_bytes: up.written,
            blocks,
            modified_unix_ms: now_ms(),
            verdict,
            revision: up.revision(),
        };
        let path = self.program_path(name);
        fs::rename(&up.tmp, &path)?;
        write_meta(&self.meta_path(name), &entry)?;
        File::open(&self.dir)?.sync_all()?;
        let opened = Arc::new(File::open(&path)?);
        self.index
            .lock()
            .unwrap()
            .insert(name.into(), entry.clone());
        Ok((entry, opened))
    }

    /// Records a new verdict (a validation at selection).
    pub fn set_verdict(&self, name: &str, blocks: u32, verdict: Verdict) -> io::Result<()> {
        let _w = self.writer.lock().unwrap();
        let mut index = self.index.lock().unwrap();
        let Some(e) = index.get_mut(name) else {
            return Ok(());
        };
        if e.verdict == verdict && e.blocks == blocks {
            return Ok(());
        }
        e.verdict = verdict;
        e.blocks = blocks;
        write_meta(&self.meta_path(name), e)
    }

    pub fn delete(&self, name: &str) -> Result<(), LibraryError> {
        let _w = self.writer.lock().unwrap();
        if self.entry(name).is_none() {
            return Err(LibraryError::NotFound(name.into()));
        }
        // The meta file first: without it the program is not listed, and the next open
        // removes nothing it should keep.
        fs::remove_file(self.meta_path(name))?;
        let _ = fs::remove_file(self.program_path(name));
        self.index.lock().unwrap().remove(name);
        Ok(())
    }

    pub fn rename(&self, from: &str, to: &str) -> Result<Entry, LibraryError> {
        let _w = self.writer.lock().unwrap();
        let mut entry = self
            .entry(from)
            .ok_or_else(|| LibraryError::NotFound(from.into()))?;
        if self.entry(to).is_some() {
            return Err(LibraryError::Exists(to.into()));
        }
        entry.name = to.into();
        fs::rename(self.program_path(from), self.program_path(to))?;
        write_meta(&self.meta_path(to), &entry)?;
        fs::remove_file(self.meta_path(from))?;
        File::open(&self.dir)?.sync_all()?;
        let mut index = self.index.lock().unwrap();
        index.remove(from);
        index.insert(to.into(), entry.clone());
        Ok(entry)
    }

    /// Remembers the selected program across restarts ("" for none).
    pub fn save_selected(&self, name: &str) -> io::Result<()> {
        write_atomic(&self.dir.join(".selected"), name.as_bytes())
    }

    /// The program selected before the last shutdown, if it is still stored.
    pub fn saved_selected(&self) -> Option<String> {
        let name = fs::read_to_string(self.dir.join(".selected")).ok()?;
        self.entry(&name).map(|e| e.name)
    }
}

/// An upload being written to its temporary file; removed unless committed.
pub struct Upload {
    tmp: PathBuf,
    file: Option<File>,
    written: u64,
    /// Bytes this upload may still take without overflowing the library.
    allowed: u64,
    max: u64,
    /// SHA-256 of the bytes written so far.
    hash: Sha256,
}

impl Upload {
    /// Appends a chunk. Refused (and nothing stored) when the library would overflow.
    pub fn write(&mut self, chunk: &[u8]) -> Result<(), LibraryError> {
        let would = self.written + chunk.len() as u64;
        if would > self.allowed {
            return Err(LibraryError::Full {
                would: self.max - self.allowed + would,
                max: self.max,
            });
        }
        self.file
            .as_mut()
            .expect("upload still open")
            .write_all(chunk)?;
        self.hash.update(chunk);
        self.written = would;
        Ok(())
    }

    pub fn written(&self) -> u64 {
        self.written
    }

    /// The revision of the text written so far (see [`Entry::revision`]).
    pub fn revision(&self) -> String {
        self.hash.clone().finalize()[..8]
            .iter()
            .map(|b| format!("{b:02x}"))
            .collect()
    }

    /// The uploaded text so far, for reading (validation).
    pub fn reopen(&self) -> io::Result<File> {
        File::open(&self.tmp)
    }
}

impl Drop for Upload {
    fn drop(&mut self) {
        if self.file.is_some() {
            let _ = fs::remove_file(&self.tmp);
        }
    }
}

fn write_meta(path: &Path, e: &Entry) -> io::Result<()> {
    let v = serde_json::json!({
        "name": e.name,
        "size_bytes": e.size_bytes,
        "blocks": e.blocks,
        "modified_unix_ms": e.modified_unix_ms,
        "valid": e.verdict.valid,
        "errors": e.verdict.errors,
        "warnings": e.verdict.warnings,
        "first_error": e.verdict.first_error,
        "revision": e.revision,
    });
    write_atomic(path, v.to_string().as_bytes())
}

fn read_meta(path: &Path) -> Option<Entry> {
    let v: serde_json::Value = serde_json::from_str(&fs::read_to_string(path).ok()?).ok()?;
    let program = path.with_extension("nc");
    let size = fs::metadata(&program).ok()?.len();
    Some(Entry {
        name: v["name"].as_str()?.to_owned(),
        size_bytes: size,
        blocks: v["blocks"].as_u64()? as u32,
        modified_unix_ms: v["modified_unix_ms"].as_u64().unwrap_or(0),
        verdict: Verdict {
            valid: v["valid"].as_bool()?,
            errors: v["errors"].as_u64().unwrap_or(0) as u32,
            warnings: v["warnings"].as_u64().unwrap_or(0) as u32,
            first_error: v["first_error"].as_str().unwrap_or("").to_owned(),
        },
        revision: v["revision"].as_str().unwrap_or("").to_owned(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use kernel::program::{self, Setup};

    /// The file stream makes the same blocks and errors as the kernel's string stream.
    #[test]
    fn file_lines_match_the_string_stream() {
        let setup = Setup::new(&['X', 'Y', 'Z']);
        for text in [
            "G1 X1 F100\nG1 Y2\n",
            "\u{FEFF}G1 X1 F100\r\nQ5\nG0 Z3",
            "",
            "\n\n",
            "G1 X1 F100\nG2 X\n",
            "G1 X1 F100\nM30\nG1 X5\n",
        ] {
            let mut a = program::stream(text, &setup);
            let mut b = program::stream_lines(FileLines::new(text.as_bytes()), &setup);
            let xa: Vec<_> = a.by_ref().collect();
            let xb: Vec<_> = b.by_ref().collect();
            assert_eq!(format!("{xa:?}"), format!("{xb:?}"), "{text:?}");
            let (na, nb) = (a.take_notes(), b.take_notes());
            assert_eq!(format!("{na:?}"), format!("{nb:?}"), "{text:?}");
        }
    }

    #[test]
    fn bad_utf8_is_located() {
        let setup = Setup::new(&['X', 'Y', 'Z']);
        let text: &[u8] = b"G1 X1 F100\nG1 (\xe8) Y2\n";
        let errs: Vec<_> = program::stream_lines(FileLines::new(text), &setup)
            .filter_map(Result::err)
            .collect();
        assert_eq!(errs.len(), 1);
        assert_eq!((errs[0].line, errs[0].column), (2, 5));
        assert_eq!(errs[0].code, DiagCode::TextNotUtf8, "{}", errs[0]);
        // The byte offset in the file (line 2 starts at 11, the bad byte is its 5th) is data
        // the machinist needs to find the byte in an editor.
        assert!(errs[0].message.contains("byte offset 15"), "{}", errs[0]);
    }
}
