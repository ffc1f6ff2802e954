//! Durable file storage: atomic replacement of TAB0.KOR, the constants file and the work
//! offsets file (`work.rs`), and the offset table's two copies, file and memory (SPEC §3).
//!
//! Every write goes through [`write_atomic`]: the new content is written to a temporary file in
//! the same directory, flushed to disk (`fsync`), renamed over the old file, and the directory
//! is flushed so the rename itself survives a power cut. A crash at any moment leaves either the
//! old or the new file, never a mix (tested by `daemon/tests/storage_kill.rs`, which SIGKILLs a
//! writer hundreds of times).
//!
//! The calls block on disk IO: from async code run them in `tokio::task::spawn_blocking`.
//! One [`OffsetStore`] per file and one writer at a time (the temporary name is fixed).
//!
//! **Files on disk are the truth** (issue #31, SPEC §3): both stores remember the bytes they
//! last saw on disk (a SHA-256). Before an API edit they look again ([`OffsetStore::sync_with_disk`],
//! [`ConstantsFile::sync_with_disk`]): a file saved by hand since is loaded first and the edit
//! applied on top of it, in its text (values replaced where they stand), so an edit never
//! overwrites what a person wrote. A hand edit that does not load refuses API edits
//! (`storage_file_invalid`) until it is fixed; the memory copy is kept meanwhile.

use std::fs::{self, File, OpenOptions};
use std::io::{self, Write};
use std::path::{Path, PathBuf};

use sha2::{Digest, Sha256};

use kernel::Diagnostic;
use kernel::constants::Constants;
use kernel::offsets::{self, KorFile, OffsetTable, TableEdit};

mod work;
pub use work::WorkOffsetStore;

/// Why a storage operation failed. Nothing was changed (neither file nor memory).
#[derive(Debug, thiserror::Error)]
pub enum StorageError {
    #[error("{path}: {source}")]
    Io {
        path: PathBuf,
        #[source]
        source: io::Error,
    },
    /// The text was refused; the messages say where and why.
    #[error("{}: {}", path.display(), join(diagnostics))]
    Invalid {
        path: PathBuf,
        diagnostics: Vec<Diagnostic>,
    },
    /// The file on disk was edited (by hand) and does not load: the memory copy is kept and
    /// API edits are refused until the file is fixed or replaced.
    #[error(
        "{} was edited on disk and does not load ({}): the controller keeps the table it had; \
         fix the file first",
        path.display(),
        join_coded(diagnostics)
    )]
    DiskInvalid {
        path: PathBuf,
        diagnostics: Vec<Diagnostic>,
    },
    /// A whole-file replacement named the revision it was made from, and the file changed since.
    #[error(
        "{} changed since revision {expected} (now {actual}): read it again and edit that",
        path.display()
    )]
    Changed {
        path: PathBuf,
        expected: String,
        actual: String,
    },
}

impl StorageError {
    /// Stable code (tests and HMIs match it; the message may improve).
    pub fn code(&self) -> &'static str {
        match self {
            StorageError::Io { .. } => "storage_io",
            StorageError::Invalid { .. } => "storage_invalid",
            StorageError::DiskInvalid { .. } => "storage_file_invalid",
            StorageError::Changed { .. } => "storage_file_changed",
        }
    }
}

fn join(d: &[Diagnostic]) -> String {
    d.iter()
        .map(ToString::to_string)
        .collect::<Vec<_>>()
        .join("; ")
}

/// `line 3, column 7 [offset_value_syntax]: …; …` (the alarm of a hand edit names the code).
fn join_coded(d: &[Diagnostic]) -> String {
    d.iter()
        .map(|d| {
            format!(
                "line {}, column {} [{}]: {}",
                d.line,
                d.column,
                d.code.as_str(),
                d.message
            )
        })
        .collect::<Vec<_>>()
        .join("; ")
}

/// Name of the temporary file used while replacing `path` (same directory, so the rename is
/// atomic; fixed, so an interrupted write leaves at most one stale temporary, overwritten next
/// time).
pub fn temp_path(path: &Path) -> PathBuf {
    let name = path
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default();
    path.with_file_name(format!(".{name}.tmp"))
}

/// Replaces `path` with `bytes` atomically and durably: temp file, fsync, rename, fsync of the
/// directory. On error the old file is untouched.
pub fn write_atomic(path: &Path, bytes: &[u8]) -> io::Result<()> {
    let tmp = temp_path(path);
    let result = (|| {
        let mut f = OpenOptions::new()
            .write(true)
            .create(true)
            .truncate(true)
            .open(&tmp)?;
        f.write_all(bytes)?;
        f.sync_all()?;
        drop(f);
        fs::rename(&tmp, path)
    })();
    if let Err(e) = result {
        let _ = fs::remove_file(&tmp);
        return Err(e);
    }
    // The rename is a change of the directory: flush it too.
    let dir = match path.parent() {
        Some(d) if !d.as_os_str().is_empty() => d,
        _ => Path::new("."),
    };
    File::open(dir)?.sync_all()
}

fn io_err(path: &Path) -> impl FnOnce(io::Error) -> StorageError + '_ {
    move |source| StorageError::Io {
        path: path.to_path_buf(),
        source,
    }
}

/// Reads and checks a constants file (format in `docs/files.md`). Parse errors and validation
/// errors are both refusals.
pub fn load_constants(path: &Path) -> Result<Constants, StorageError> {
    let text = fs::read_to_string(path).map_err(io_err(path))?;
    let invalid = |diagnostics| StorageError::Invalid {
        path: path.to_path_buf(),
        diagnostics,
    };
    let c = Constants::parse(&text).map_err(invalid)?;
    let errs = c.validate();
    if errs.is_empty() {
        Ok(c)
    } else {
        Err(invalid(errs))
    }
}

/// Writes the constants file atomically (only constants that were set, see
/// [`Constants::to_text`]). Refuses constants that do not validate.
pub fn save_constants(path: &Path, c: &Constants) -> Result<(), StorageError> {
    let errs = c.validate();
    if !errs.is_empty() {
        return Err(StorageError::Invalid {
            path: path.to_path_buf(),
            diagnostics: errs,
        });
    }
    write_atomic(path, c.to_text().as_bytes()).map_err(io_err(path))
}

/// SHA-256 of a file's bytes: what the stores remember of the disk.
pub type Fingerprint = [u8; 32];

pub fn fingerprint(bytes: &[u8]) -> Fingerprint {
    Sha256::digest(bytes).into()
}

/// The revision of a text as the API shows it: the first 16 hex digits of its SHA-256.
pub fn revision_of(f: &Fingerprint) -> String {
    f[..8].iter().map(|b| format!("{b:02x}")).collect()
}

/// The bytes of `path`, `None` when it does not exist.
fn read_disk(path: &Path) -> Result<Option<Vec<u8>>, StorageError> {
    match fs::read(path) {
        Ok(b) => Ok(Some(b)),
        Err(e) if e.kind() == io::ErrorKind::NotFound => Ok(None),
        Err(e) => Err(io_err(path)(e)),
    }
}

/// A text from disk, or the diagnostic of a file that is not UTF-8.
fn utf8(bytes: Vec<u8>) -> Result<String, Vec<Diagnostic>> {
    String::from_utf8(bytes).map_err(|e| {
        let line = e.as_bytes()[..e.utf8_error().valid_up_to()]
            .iter()
            .filter(|&&b| b == b'\n')
            .count() as u32
            + 1;
        vec![Diagnostic::error(
            kernel::DiagCode::OffsetFileSyntax,
            None,
            line,
            1,
            "the file is not UTF-8 text",
        )]
    })
}

/// What a look at the disk found.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum DiskChange {
    /// The bytes are those last seen (or written).
    Unchanged,
    /// The file was saved since and loaded: memory follows it (SPEC §3 a).
    Loaded,
    /// The file is gone: the controller keeps what it has; the next edit writes it again.
    Missing,
}

/// The offset table TAB0.KOR: the file and the memory copy the controller works with (SPEC §3).
///
/// - power-on / [`OffsetStore::load`]: the file is read into memory;
/// - (a) [`OffsetStore::save_file_text`], or the file saved by hand and seen by
///   [`OffsetStore::sync_with_disk`]: memory becomes the file's table (values written by G92
///   are replaced, as in the manual);
/// - (b) [`OffsetStore::operator_edit`]: an operator edit goes to the file **and** memory; the
///   file's text is edited in place (`kernel::offsets::edit_text`), on top of the file as it
///   is on disk now;
/// - (c) [`OffsetStore::program_write`]: `G92` writes memory only.
///
/// Every call is all-or-nothing: a refused text or value, or a failed disk write, changes
/// neither the file nor memory.
#[derive(Debug)]
pub struct OffsetStore {
    path: PathBuf,
    axis_names: Vec<char>,
    /// The last text of the file that loaded.
    file: KorFile,
    memory: OffsetTable,
    /// The file's text as last seen on disk or written (what `offsets-file` shows).
    text: String,
    /// The bytes last seen on disk (`None`: no file yet).
    seen: Option<Fingerprint>,
    /// The text on disk does not load (a hand edit): why. Memory and `file` are the last good.
    disk_error: Option<Vec<Diagnostic>>,
}

impl OffsetStore {
    /// Power-on: reads the file into memory.
    pub fn load(path: impl Into<PathBuf>, axis_names: &[char]) -> Result<Self, StorageError> {
        let path = path.into();
        let bytes = fs::read(&path).map_err(io_err(&path))?;
        let seen = Some(fingerprint(&bytes));
        let invalid = |diagnostics| StorageError::Invalid {
            path: path.clone(),
            diagnostics,
        };
        let text = utf8(bytes).map_err(invalid)?;
        let file = offsets::parse(&text, axis_names).map_err(invalid)?;
        Ok(OffsetStore {
            memory: file.table.clone(),
            path,
            axis_names: axis_names.to_vec(),
            file,
            text,
            seen,
            disk_error: None,
        })
    }

    /// Power-on when the file may not exist yet: a missing file is an empty (all zero) table
    /// and is created on the first save or operator edit.
    pub fn load_or_empty(
        path: impl Into<PathBuf>,
        axis_names: &[char],
    ) -> Result<Self, StorageError> {
        let path = path.into();
        match fs::metadata(&path) {
            Err(e) if e.kind() == io::ErrorKind::NotFound => Ok(OffsetStore {
                text: offsets::write(&KorFile::default(), axis_names),
                path,
                axis_names: axis_names.to_vec(),
                file: KorFile::default(),
                memory: OffsetTable::new(),
                seen: None,
                disk_error: None,
            }),
            _ => Self::load(path, axis_names),
        }
    }

    pub fn path(&self) -> &Path {
        &self.path
    }

    /// The table the controller works with (the interpreter's `Setup::offsets` at program start).
    pub fn memory(&self) -> &OffsetTable {
        &self.memory
    }

    /// The table as it is in the file (the last text that loaded).
    pub fn file(&self) -> &KorFile {
        &self.file
    }

    /// The file's text as it is on disk (as last seen; a hand edit that does not load
    /// included, see [`OffsetStore::disk_error`]).
    pub fn file_text(&self) -> String {
        self.text.clone()
    }

    /// The revision of [`OffsetStore::file_text`] (see [`revision_of`]); empty without a file.
    pub fn revision(&self) -> String {
        self.seen.as_ref().map(revision_of).unwrap_or_default()
    }

    /// Why the text on disk does not load, when it does not.
    pub fn disk_error(&self) -> Option<&[Diagnostic]> {
        self.disk_error.as_deref()
    }

    /// Looks at the file: a text saved since it was last seen is loaded (memory = file, SPEC
    /// §3 a); one that does not load is refused with its lines and codes (`storage_file_invalid`)
    /// and memory is kept. Repeats the refusal while the file stays so.
    pub fn sync_with_disk(&mut self) -> Result<DiskChange, StorageError> {
        let Some(bytes) = read_disk(&self.path)? else {
            return Ok(DiskChange::Missing);
        };
        let f = fingerprint(&bytes);
        if self.seen != Some(f) {
            self.seen = Some(f);
            let parsed = utf8(bytes).and_then(|t| {
                let p = offsets::parse(&t, &self.axis_names);
                self.text = t;
                p
            });
            match parsed {
                Ok(file) => {
                    self.memory = file.table.clone();
                    self.file = file;
                    self.disk_error = None;
                    return Ok(DiskChange::Loaded);
                }
                Err(d) => self.disk_error = Some(d),
            }
        }
        match &self.disk_error {
            Some(d) => Err(StorageError::DiskInvalid {
                path: self.path.clone(),
                diagnostics: d.clone(),
            }),
            None => Ok(DiskChange::Unchanged),
        }
    }

    /// Writes `text` (already checked) and remembers it as seen.
    fn write_text(&mut self, text: String) -> Result<(), StorageError> {
        write_atomic(&self.path, text.as_bytes()).map_err(io_err(&self.path))?;
        self.seen = Some(fingerprint(text.as_bytes()));
        self.text = text;
        self.disk_error = None;
        Ok(())
    }

    /// (a) Saves an edited file: checked, written atomically, then memory = file.
    pub fn save_file_text(&mut self, text: &str) -> Result<(), StorageError> {
        self.replace_file_text(text, None)
    }

    /// (a) As [`OffsetStore::save_file_text`]; with `base_revision` the file must still be the
    /// one of that revision (else `storage_file_changed`: someone saved it since it was read).
    pub fn replace_file_text(
        &mut self,
        text: &str,
        base_revision: Option<&str>,
    ) -> Result<(), StorageError> {
        let file = offsets::parse(text, &self.axis_names).map_err(|diagnostics| {
            StorageError::Invalid {
                path: self.path.clone(),
                diagnostics,
            }
        })?;
        if let Some(expected) = base_revision {
            // A file that does not load may be replaced: that is how it gets fixed.
            let _ = self.sync_with_disk();
            if self.revision() != expected {
                return Err(StorageError::Changed {
                    path: self.path.clone(),
                    expected: expected.into(),
                    actual: self.revision(),
                });
            }
        }
        self.write_text(text.to_string())?;
        self.memory = file.table.clone();
        self.file = file;
        Ok(())
    }

    /// (b) Operator edit of one entry: the values present change in the file and in memory.
    /// A file saved by hand since it was last seen is loaded first and the edit made on top of
    /// its text, which keeps every other byte.
    pub fn operator_edit(&mut self, edit: &TableEdit) -> Result<(), StorageError> {
        let path = self.path.clone();
        let refuse = |e: offsets::OffsetError| StorageError::Invalid {
            path: path.clone(),
            diagnostics: vec![Diagnostic::error(e.code(), None, 0, 0, e.to_string())],
        };
        let mut memory = self.memory.clone();
        memory.apply(edit).map_err(refuse)?;
        match self.sync_with_disk()? {
            DiskChange::Loaded => {
                memory = self.memory.clone();
                memory.apply(edit).map_err(refuse)?;
            }
            DiskChange::Unchanged | DiskChange::Missing => {}
        }
        let (text, file) =
            offsets::edit_text(&self.text, edit, &self.axis_names).map_err(|diagnostics| {
                StorageError::Invalid {
                    path: self.path.clone(),
                    diagnostics,
                }
            })?;
        self.write_text(text)?;
        self.file = file;
        self.memory = memory;
        Ok(())
    }

    /// (b) Operator edit written like a file line, e.g. `12: R=5.0 Z=-3`.
    pub fn operator_edit_text(&mut self, line: &str) -> Result<(), StorageError> {
        let edit =
            offsets::parse_edit(line, &self.axis_names).map_err(|d| StorageError::Invalid {
                path: self.path.clone(),
                diagnostics: vec![d],
            })?;
        self.operator_edit(&edit)
    }

    /// (c) `G92 D<n> R0..R4` executed (a `BlockKind::TableWrite`): memory only.
    pub fn program_write(&mut self, edit: &TableEdit) -> Result<(), offsets::OffsetError> {
        self.memory.apply(edit)
    }
}

/// The constants file (TAB0.REK by default): its text as a person wrote it. Setting constants
/// edits the text in place (`kernel::constants::edit_text`) on top of the file as it is on disk.
#[derive(Debug)]
pub struct ConstantsFile {
    path: PathBuf,
    /// The text as last seen or written; `None` while there is no file.
    text: Option<String>,
    seen: Option<Fingerprint>,
    disk_error: Option<Vec<Diagnostic>>,
}

impl ConstantsFile {
    /// Power-on: the constants of the file (checked), or `None` when there is no file.
    pub fn open(path: impl Into<PathBuf>) -> Result<(Self, Option<Constants>), StorageError> {
        let path = path.into();
        let mut f = ConstantsFile {
            path,
            text: None,
            seen: None,
            disk_error: None,
        };
        match f.sync_with_disk() {
            Ok(c) => Ok((f, c)),
            Err(StorageError::DiskInvalid { path, diagnostics }) => {
                Err(StorageError::Invalid { path, diagnostics })
            }
            Err(e) => Err(e),
        }
    }

    pub fn path(&self) -> &Path {
        &self.path
    }

    /// Why the text on disk does not load, when it does not.
    pub fn disk_error(&self) -> Option<&[Diagnostic]> {
        self.disk_error.as_deref()
    }

    /// Looks at the file: the constants of a text saved since it was last seen (checked), or
    /// `None` when nothing changed (or the file is gone). A text that does not load or check is
    /// refused (`storage_file_invalid`), again on every call while the file stays so.
    pub fn sync_with_disk(&mut self) -> Result<Option<Constants>, StorageError> {
        let Some(bytes) = read_disk(&self.path)? else {
            return Ok(None);
        };
        let f = fingerprint(&bytes);
        if self.seen != Some(f) {
            self.seen = Some(f);
            let parsed = utf8(bytes).and_then(|t| {
                let c = Constants::parse(&t).and_then(|c| {
                    let errs = c.validate();
                    if errs.is_empty() { Ok(c) } else { Err(errs) }
                });
                self.text = Some(t);
                c
            });
            match parsed {
                Ok(c) => {
                    self.disk_error = None;
                    return Ok(Some(c));
                }
                Err(d) => self.disk_error = Some(d),
            }
        }
        match &self.disk_error {
            Some(d) => Err(StorageError::DiskInvalid {
                path: self.path.clone(),
                diagnostics: d.clone(),
            }),
            None => Ok(None),
        }
    }

    /// Sets `values` (constant, thousandths) in the file's text, or in `base`'s text when there
    /// is no file yet, and writes it atomically. Call [`ConstantsFile::sync_with_disk`] first:
    /// the edit is made on the text last seen. Returns the constants of the new text.
    pub fn set(
        &mut self,
        base: &Constants,
        values: &[(u16, i64)],
    ) -> Result<Constants, StorageError> {
        let invalid = |diagnostics| StorageError::Invalid {
            path: self.path.clone(),
            diagnostics,
        };
        let current = self.text.clone().unwrap_or_else(|| base.to_text());
        let (text, c) = kernel::constants::edit_text(&current, values).map_err(invalid)?;
        let errs = c.validate();
        if !errs.is_empty() {
            return Err(invalid(errs));
        }
        write_atomic(&self.path, text.as_bytes()).map_err(io_err(&self.path))?;
        self.seen = Some(fingerprint(text.as_bytes()));
        self.text = Some(text);
        self.disk_error = None;
        Ok(c)
    }
}
