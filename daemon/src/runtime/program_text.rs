//! The text of a program as the pipeline reads it: in memory, or an open file of the library
//! read line by line through a fixed buffer (issue #19; see `library` for why a program runs
//! from its open file).

use std::fs::File;
use std::io::{self, BufRead, BufReader, Cursor, Read, Seek, SeekFrom};
use std::os::unix::fs::FileExt;
use std::sync::Arc;

use kernel::machine::MachineSetup;
use kernel::pipeline::{self, Observer, Options, Summary, Validation};
use kernel::program::encoding::TextEncoding;
use kernel::program::{LineMark, Lines, StrLines};

use super::split_pass::{self, SPLIT_MIN_BYTES};
use kernel::{DiagCode, Diagnostic};

/// Read buffer of a program streamed from its file.
pub(crate) const READ_BUFFER_BYTES: usize = 256 * 1024;

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
        // A large text: the interpreter on a thread of its own (`split_pass`).
        let split = self.len() >= SPLIT_MIN_BYTES;
        match self {
            ProgramText::Memory(t) if split => {
                split_pass::validate_lines(StrLines::new(t), setup, opts, inner)
            }
            ProgramText::Memory(t) => pipeline::validate_into(t, setup, opts, inner),
            ProgramText::File(f) => {
                let lines = FileLines::open(f).with_encoding(setup.program().encoding);
                if split {
                    split_pass::validate_lines(lines, setup, opts, inner)
                } else {
                    pipeline::validate_lines_into(lines, setup, opts, inner)
                }
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

impl Seek for PosReader {
    fn seek(&mut self, to: SeekFrom) -> io::Result<u64> {
        let from_end = |d: i64| -> io::Result<u64> {
            let len = self.file.metadata()?.len();
            Ok(len.saturating_add_signed(d))
        };
        self.pos = match to {
            SeekFrom::Start(p) => p,
            SeekFrom::Current(d) => self.pos.checked_add_signed(d).ok_or_else(before_start)?,
            SeekFrom::End(d) => from_end(d)?,
        };
        Ok(self.pos)
    }
}

fn before_start() -> io::Error {
    io::Error::new(io::ErrorKind::InvalidInput, "seek before the start")
}

/// A program's reader that can go back to a byte offset of its source: the ISO dialect's
/// loops and subroutine calls read lines again (`kernel::program::Lines::seek`).
pub trait Reposition: BufRead {
    /// Whether [`Reposition::reposition`] works (a stream of chunks cannot go back).
    fn can_reposition(&self) -> bool {
        true
    }

    /// Continues reading at byte `offset` of the source.
    fn reposition(&mut self, offset: u64) -> io::Result<()>;
}

impl<R: Read + Seek> Reposition for BufReader<R> {
    fn reposition(&mut self, offset: u64) -> io::Result<()> {
        // Relative to where the buffer stands: a loop's body usually still is in the buffer.
        let now = self.stream_position()?;
        let delta = i64::try_from(offset as i128 - now as i128).map_err(|_| before_start())?;
        self.seek_relative(delta)
    }
}

impl<T: AsRef<[u8]>> Reposition for Cursor<T> {
    fn reposition(&mut self, offset: u64) -> io::Result<()> {
        self.set_position(offset);
        Ok(())
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
    /// Where the text ended (`offset` after its last line), once read to its end.
    end: Option<u64>,
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

impl<R: Reposition> FileLines<R> {
    pub fn new(reader: R) -> Self {
        FileLines {
            reader,
            line: Vec::with_capacity(256),
            encoding: TextEncoding::Utf8,
            decoded: String::new(),
            offset: 0,
            done: false,
            end: None,
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

impl<R: Reposition> Lines for FileLines<R> {
    fn next_line(&mut self, line_no: u32) -> Option<Result<&str, Diagnostic>> {
        if self.done {
            return None;
        }
        self.line.clear();
        if let Err(e) = self.reader.read_until(b'\n', &mut self.line) {
            self.done = true;
            self.end = Some(self.offset);
            let msg = format!("cannot read the program file: {e}");
            return Some(Err(Diagnostic::error(
                DiagCode::ProgramUnreadable,
                None,
                line_no,
                0,
                msg,
            )));
        }
        let start = self.offset;
        if self.line.last() == Some(&b'\n') {
            self.line.pop();
            self.offset += self.line.len() as u64 + 1;
        } else {
            // The last line: the offset goes one past the text's end, as the kernel's
            // string lines do (a mark taken here means "nothing left").
            self.done = true;
            self.offset += self.line.len() as u64 + 1;
            self.end = Some(self.offset);
        }
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

    fn mark(&self) -> Option<LineMark> {
        self.reader
            .can_reposition()
            .then_some(LineMark(self.offset))
    }

    fn seek(&mut self, mark: LineMark) -> bool {
        if !self.reader.can_reposition() {
            return false;
        }
        // A mark at (or past) the end read so far: nothing left to read.
        if self.end.is_some_and(|end| mark.0 >= end) {
            self.offset = mark.0;
            self.done = true;
            return true;
        }
        if self.reader.reposition(mark.0).is_err() {
            return false;
        }
        self.offset = mark.0;
        self.done = false;
        true
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use kernel::program::{self, Dialect, Setup};

    fn lines_of(text: &[u8]) -> FileLines<Cursor<&[u8]>> {
        FileLines::new(Cursor::new(text))
    }

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
            let mut b = program::stream_lines(lines_of(text.as_bytes()), &setup);
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
        let errs: Vec<_> = program::stream_lines(lines_of(text), &setup)
            .filter_map(Result::err)
            .collect();
        assert_eq!(errs.len(), 1);
        assert_eq!((errs[0].line, errs[0].column), (2, 5));
        assert_eq!(errs[0].code, DiagCode::TextNotUtf8, "{}", errs[0]);
        // The byte offset in the file (line 2 starts at 11, the bad byte is its 5th) is data
        // the machinist needs to find the byte in an editor.
        assert!(errs[0].message.contains("byte offset 15"), "{}", errs[0]);
    }

    /// The lines read from `l` until the end (at most 100), as text.
    fn rest(l: &mut (impl Lines + ?Sized)) -> Vec<String> {
        let mut out = Vec::new();
        while let Some(line) = l.next_line(0) {
            out.push(line.map(str::to_string).unwrap_or_else(|d| d.message));
            if out.len() > 100 {
                break;
            }
        }
        out
    }

    /// An open file read through a buffer smaller than the text: a seek back lands outside
    /// the buffer, one forward inside it.
    fn small_buffer_file(text: &[u8]) -> FileLines<BufReader<PosReader>> {
        let path = std::env::temp_dir().join(format!("cncd-seek-{}.ngc", std::process::id()));
        std::fs::write(&path, text).unwrap();
        let f = Arc::new(File::open(&path).unwrap());
        std::fs::remove_file(&path).unwrap();
        FileLines::new(BufReader::with_capacity(8, PosReader::new(f)))
    }

    #[test]
    fn a_mark_reads_the_same_lines_again() {
        let text = b"first line\nsecond\r\nthird one\n\nlast";
        for (l, name) in [
            (&mut lines_of(text) as &mut dyn Lines, "memory"),
            (&mut small_buffer_file(text), "file"),
        ] {
            assert_eq!(l.next_line(1).unwrap().unwrap(), "first line", "{name}");
            let m = l.mark().expect("a file can go back");
            let after = rest(l);
            assert_eq!(after, ["second\r", "third one", "", "last"], "{name}");
            let end = l.mark().unwrap();
            assert!(l.seek(m), "{name}");
            assert_eq!(rest(l), after, "{name}: the same lines again");
            // A mark at the end: nothing more, again and again.
            assert!(l.seek(end), "{name}");
            assert!(l.next_line(9).is_none(), "{name}");
            assert!(l.seek(LineMark(0)), "{name}");
            assert_eq!(l.next_line(1).unwrap().unwrap(), "first line", "{name}");
        }
    }

    /// An ISO program with a loop and a subroutine reads from its file as from a string.
    #[test]
    fn iso_loops_and_calls_run_from_a_file() {
        let mut setup = Setup::new(&['X', 'Y', 'Z']);
        setup.dialect = Dialect::Iso;
        let text = "G21 G90 G17\n#1 = 0\no100 while [#1 LT 3]\nG1 X[#1 * 10] F500\n\
                    #1 = [#1 + 1]\no100 endwhile\no200 call\nM30\n\
                    o200 sub\nG0 Y5\no200 endsub\n";
        let a: Vec<_> = program::stream(text, &setup).collect();
        let b: Vec<_> = program::stream_lines(small_buffer_file(text.as_bytes()), &setup).collect();
        assert_eq!(format!("{a:?}"), format!("{b:?}"));
        assert!(a.iter().all(Result::is_ok), "{a:?}");
        assert!(a.len() >= 4, "{a:?}");
    }
}
