//! The text of a program as the pipeline reads it: in memory, or an open file of the library
//! read line by line through a fixed buffer (issue #19; see `library` for why a program runs
//! from its open file).

use std::fs::File;
use std::io::{self, BufRead, BufReader, Read};
use std::os::unix::fs::FileExt;
use std::sync::Arc;

use kernel::machine::MachineSetup;
use kernel::pipeline::{self, Observer, Options, Summary, Validation};
use kernel::program::Lines;
use kernel::program::encoding::TextEncoding;
use kernel::{DiagCode, Diagnostic};

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
