//! Part-program parser and interpreter (SPEC §2, §5).
//!
//! Walking-skeleton subset: `N`, `G0 G1 G90 G91`, axis words, `F` (G94 mm/min; with a decimal
//! point m/min, SPEC §5), `;` comments. The full CNC836 dialect is issue #3.

use crate::block::{Block, BlockKind, Feed, Path};
use crate::diag::Diagnostic;
use crate::units::{AxesMm, MAX_AXES};

/// Feed limit under G94 (SPEC §5).
pub const MAX_FEED_MM_MIN: f64 = 90_000.0;

/// What the interpreter needs to know about the machine.
#[derive(Clone, Debug, PartialEq)]
pub struct Setup {
    /// Axis letters in machine order (R0..R5), e.g. `['X', 'Y', 'Z']`.
    pub axis_names: Vec<char>,
    /// Position of the axes when the program starts.
    pub start: AxesMm,
}

impl Setup {
    pub fn new(axis_names: &[char]) -> Self {
        Setup {
            axis_names: axis_names.to_vec(),
            start: AxesMm::ZERO,
        }
    }
}

/// A validated program: its canonical blocks and every message about it.
#[derive(Clone, Debug, Default)]
pub struct Compiled {
    pub blocks: Vec<Block>,
    pub diagnostics: Vec<Diagnostic>,
}

impl Compiled {
    pub fn has_errors(&self) -> bool {
        self.diagnostics.iter().any(Diagnostic::is_error)
    }
}

/// Parses and interprets a whole program. Blocks are produced only if there is no error.
pub fn compile(text: &str, setup: &Setup) -> Compiled {
    let mut interp = Interpreter::new(setup);
    let mut out = Compiled::default();
    for (i, line) in text.lines().enumerate() {
        match interp.line(i as u32 + 1, line) {
            Ok(Some(b)) => out.blocks.push(b),
            Ok(None) => {}
            Err(d) => out.diagnostics.push(d),
        }
    }
    if out.has_errors() {
        out.blocks.clear();
    }
    out
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum MotionMode {
    Rapid,
    Linear,
}

/// Modal state and position, advanced block by block.
pub struct Interpreter {
    axis_names: Vec<char>,
    pos: AxesMm,
    motion: MotionMode,
    absolute: bool,
    feed_mm_min: f64,
    seq: u32,
}

impl Interpreter {
    pub fn new(setup: &Setup) -> Self {
        Interpreter {
            axis_names: setup.axis_names.clone(),
            pos: setup.start,
            motion: MotionMode::Rapid,
            absolute: true,
            feed_mm_min: 0.0,
            seq: 0,
        }
    }

    /// Interprets one source line. Returns the canonical block it makes, if any.
    /// On error the modal state is unchanged.
    pub fn line(&mut self, line_no: u32, text: &str) -> Result<Option<Block>, Diagnostic> {
        let code = text.split(';').next().unwrap_or("");
        let bytes = code.as_bytes();
        let mut i = 0;
        let mut n = None;
        let mut motion = self.motion;
        let mut absolute = self.absolute;
        let mut feed = self.feed_mm_min;
        let mut targets: [Option<f64>; MAX_AXES] = [None; MAX_AXES];
        let mut any_word = false;
        while i < bytes.len() {
            let c = bytes[i] as char;
            if c.is_ascii_whitespace() {
                i += 1;
                continue;
            }
            let col = i as u32 + 1;
            let letter = c.to_ascii_uppercase();
            i += 1;
            let start = i;
            while i < bytes.len()
                && (bytes[i].is_ascii_digit() || matches!(bytes[i], b'.' | b'-' | b'+'))
            {
                i += 1;
            }
            let num = &code[start..i];
            let err = |msg: String| Diagnostic::error(n, line_no, col, msg);
            if !letter.is_ascii_alphabetic() {
                return Err(err(format!("unexpected character '{c}'")));
            }
            if num.is_empty() {
                return Err(err(format!("address {letter} has no value")));
            }
            let value: f64 = num
                .parse()
                .map_err(|_| err(format!("'{num}' is not a number (address {letter})")))?;
            any_word = true;
            match letter {
                'N' => n = Some(value as u32),
                'G' => match num {
                    "0" | "00" => motion = MotionMode::Rapid,
                    "1" | "01" => motion = MotionMode::Linear,
                    "90" => absolute = true,
                    "91" => absolute = false,
                    _ => return Err(err(format!("G{num} is not supported"))),
                },
                'F' => {
                    // SPEC §5: with a decimal point F is in m/min.
                    let f = if num.contains('.') {
                        value * 1000.0
                    } else {
                        value
                    };
                    if !(0.0..=MAX_FEED_MM_MIN).contains(&f) {
                        return Err(err(format!(
                            "feed {f} mm/min is outside 0..{MAX_FEED_MM_MIN} mm/min"
                        )));
                    }
                    feed = f;
                }
                _ => match self.axis_names.iter().position(|&a| a == letter) {
                    Some(ax) => targets[ax] = Some(value),
                    None => return Err(err(format!("unknown address {letter}"))),
                },
            }
        }
        if !any_word {
            return Ok(None);
        }
        let mut end = self.pos;
        for (ax, t) in targets.iter().enumerate() {
            if let Some(v) = t {
                end[ax] = if absolute { *v } else { self.pos[ax] + v };
            }
        }
        let moves = targets.iter().any(Option::is_some);
        if moves && motion == MotionMode::Linear && feed <= 0.0 {
            return Err(Diagnostic::error(
                n,
                line_no,
                1,
                "G1 without a feed: program F before the first feed move",
            ));
        }
        let kind = if moves {
            BlockKind::Motion {
                start: self.pos,
                end,
                path: if motion == MotionMode::Rapid {
                    Path::Rapid
                } else {
                    Path::Line
                },
            }
        } else {
            BlockKind::Technology
        };
        let block = Block {
            seq: self.seq,
            n,
            line: line_no,
            kind,
            feed: Feed::MmPerMin(feed),
            plane: Default::default(),
            comp: Default::default(),
            continuity: Default::default(),
            dyn_set: 1,
            spindle: Default::default(),
            m: [None; 4],
        };
        self.seq += 1;
        self.pos = end;
        self.motion = motion;
        self.absolute = absolute;
        self.feed_mm_min = feed;
        Ok(Some(block))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn setup() -> Setup {
        Setup::new(&['X', 'Y', 'Z'])
    }

    #[test]
    fn lines_and_rapids() {
        let c = compile(
            "N10 G0 X10 Y5\nN20 G1 X20 F600 ; cut\nN30 G91 Y-5\n",
            &setup(),
        );
        assert!(!c.has_errors(), "{:?}", c.diagnostics);
        assert_eq!(c.blocks.len(), 3);
        let (_, end, path) = c.blocks[2].motion().unwrap();
        assert_eq!(path, Path::Line);
        assert_eq!(&end.0[..3], &[20.0, 0.0, 0.0]);
        assert_eq!(c.blocks[1].feed, Feed::MmPerMin(600.0));
    }

    #[test]
    fn feed_with_decimal_point_is_m_per_min() {
        let c = compile("G1 X1 F1.2", &setup());
        assert_eq!(c.blocks[0].feed, Feed::MmPerMin(1200.0));
    }

    #[test]
    fn unknown_word_and_missing_value_are_located() {
        let c = compile("N10 G1 X1 F100\nN20 Q5\nN30 X\n", &setup());
        assert!(c.blocks.is_empty());
        assert_eq!(c.diagnostics.len(), 2);
        assert_eq!(c.diagnostics[0].block, Some(20));
        assert_eq!((c.diagnostics[0].line, c.diagnostics[0].column), (2, 5));
        assert!(c.diagnostics[0].message.contains("unknown address Q"));
        assert_eq!(c.diagnostics[1].block, Some(30));
        assert!(c.diagnostics[1].message.contains("no value"));
    }

    #[test]
    fn g1_without_feed_is_an_error() {
        let c = compile("N5 G1 X1", &setup());
        assert!(c.has_errors());
        assert_eq!(c.diagnostics[0].block, Some(5));
    }
}
