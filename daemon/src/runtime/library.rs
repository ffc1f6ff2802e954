//! The program library on disk, and programs read from files (issue #19).
//!
//! - Every stored program is a file in `storage.programs_dir` (name: a hash of the program's
//!   name, so any printable name is safe on disk) beside a small `.meta` file (name, blocks,
//!   validation verdict). Both are written atomically (temporary file, fsync, rename): a crash
//!   leaves the old program or the new one. The library survives restarts; its size is bounded
//!   by `storage.programs_max_bytes`. The selected program's name is kept in `.selected`.
//! - A program runs from its file: [`ProgramText::File`] holds the open file of the version
//!   that was validated (a later upload under the same name replaces the directory entry, not
//!   the open file), and [`FileLines`] (`program_text.rs`) feeds its lines through a fixed buffer into the one
//!   pipeline (`kernel::pipeline::run_lines`), so validation and run see what a string would
//!   give and memory stays bounded by the look-ahead whatever the program's size.
//!
//! The calls block on disk IO: from async code run them in `spawn_blocking`.

use std::collections::BTreeMap;
use std::fs::{self, File, OpenOptions};
use std::io::{self, Write};
use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex};
use std::time::{SystemTime, UNIX_EPOCH};

use kernel::Diagnostic;
use kernel::program::Dialect;
use sha2::{Digest, Sha256};

use super::arrival::{Arrival, End};
use super::storage::write_atomic;

pub use super::program_text::{FileLines, PosReader, ProgramText};

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
    /// The language chosen for it over the API (upload or selection); `None`: by its name,
    /// else the machine's `[program] dialect` (`runtime::dialect`).
    pub dialect: Option<Dialect>,
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
            arrival: Arrival::new(),
        })
    }

    /// Stores an upload under `name` (replacing a program of that name) with its verdict and
    /// the dialect chosen for it (`None`: by its name). Returns the entry and the stored
    /// file, opened.
    pub fn commit(
        &self,
        name: &str,
        mut up: Upload,
        blocks: u32,
        verdict: Verdict,
        dialect: Option<Dialect>,
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
            dialect,
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

    /// Records the dialect chosen for a stored program at its selection.
    pub fn set_dialect(&self, name: &str, dialect: Dialect) -> io::Result<()> {
        let _w = self.writer.lock().unwrap();
        let mut index = self.index.lock().unwrap();
        let Some(e) = index.get_mut(name) else {
            return Ok(());
        };
        if e.dialect == Some(dialect) {
            return Ok(());
        }
        e.dialect = Some(dialect);
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
    /// What its readers may read of it ([`Upload::arrival`]).
    arrival: Arc<Arrival>,
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
        self.arrival.wrote(would);
        Ok(())
    }

    /// Every byte is written: a reader of the upload reads to its end and stops there.
    pub fn complete(&self) {
        self.arrival.end(End::Complete);
    }

    /// What has arrived of the upload, for reading it while it is written
    /// ([`crate::runtime::arrival::ArrivingReader`] over [`Upload::reopen`]).
    pub fn arrival(&self) -> Arc<Arrival> {
        self.arrival.clone()
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
    /// An upload dropped before it was complete is abandoned: its readers stop.
    fn drop(&mut self) {
        self.arrival.end(End::Abandoned);
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
        "dialect": e.dialect.map(Dialect::as_str),
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
        // A program stored before dialects were kept: by its name.
        dialect: v["dialect"].as_str().and_then(Dialect::from_name),
    })
}
