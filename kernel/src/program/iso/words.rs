//! The evaluated words of one ISO line, sorted into LinuxCNC's modal groups and checked on
//! their own: which G and M codes and letters cncd runs (docs/language.md, "ISO programs").
//! Everything else is refused here with `iso_unsupported`, naming the word.

use super::Fail;
use super::state::{CompSide, FeedMode, MotionMode};
use crate::block::Plane;
use crate::diag::DiagCode;
use crate::units::MAX_AXES;

/// A value and the byte offset of its letter.
pub type At<T> = Option<(T, usize)>;

/// Non-modal G codes (group 0).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum NonModal {
    Dwell,
    /// G10 L2 / L20: set a work offset.
    SetWorkOffset,
    MachineCoords,
    /// G92, G92.1.
    G92Set,
    G92Cancel,
}

/// Path control (G61, G61.1, G64).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum PathMode {
    ExactPath,
    ExactStop,
    Blend,
}

/// The words of one line, after evaluation (values in the program's units).
#[derive(Clone, Debug, Default)]
pub struct Words {
    pub motion: At<MotionMode>,
    pub non_modal: At<NonModal>,
    pub plane: At<Plane>,
    pub inches: At<bool>,
    pub absolute: At<bool>,
    pub arc_absolute: At<bool>,
    pub feed_mode: At<FeedMode>,
    pub comp: At<CompSide>,
    /// G43 (true) / G49 (false).
    pub length: At<bool>,
    pub system: At<usize>,
    pub path: At<PathMode>,
    pub retract_to_r: At<bool>,
    pub axes: [At<f64>; MAX_AXES],
    pub i: At<f64>,
    pub j: At<f64>,
    pub k: At<f64>,
    pub r: At<f64>,
    pub p: At<f64>,
    pub q: At<f64>,
    pub l: At<f64>,
    pub d: At<f64>,
    pub h: At<f64>,
    pub f: At<f64>,
    pub s: At<f64>,
    pub t: At<f64>,
    /// M0 M1 M2 M30.
    pub stop: At<u16>,
    pub m6: Option<usize>,
    pub spindle: At<u16>,
    /// M7, M8, M9 (M7 and M8 may stand together).
    pub coolant: Vec<(u16, usize)>,
    /// M codes the machine binds to outputs or inputs (`[io]`).
    pub bound: Vec<(u16, usize)>,
    /// Byte offset of the first word, for errors about the whole line.
    pub first: usize,
}

impl Words {
    /// Any axis word.
    pub fn any_axis(&self) -> bool {
        self.axes.iter().any(Option::is_some)
    }
}

fn unsupported(at: usize, what: impl std::fmt::Display) -> Fail {
    Fail::new(
        at,
        DiagCode::IsoUnsupported,
        format!("{what} is not a function of cncd's ISO dialect (docs/language.md)"),
    )
}

fn once<T>(slot: &mut At<T>, v: T, at: usize, what: &str) -> Result<(), Fail> {
    if slot.is_some() {
        return Err(Fail::new(
            at,
            DiagCode::IsoModalConflict,
            format!("{what} is written twice in this line (or two codes of its modal group)"),
        ));
    }
    *slot = Some((v, at));
    Ok(())
}

/// The G code `g` (tenths: G59.1 is 591) into its group.
pub fn g_word(w: &mut Words, g10: u32, at: usize) -> Result<(), Fail> {
    const MOTION: &str = "a motion code (G0..G3, G38.2..G38.5, G73, G80..G89)";
    let name = if g10.is_multiple_of(10) {
        format!("G{}", g10 / 10)
    } else {
        format!("G{}.{}", g10 / 10, g10 % 10)
    };
    match g10 {
        0 => once(&mut w.motion, MotionMode::Rapid, at, MOTION),
        10 => once(&mut w.motion, MotionMode::Line, at, MOTION),
        20 => once(&mut w.motion, MotionMode::Cw, at, MOTION),
        30 => once(&mut w.motion, MotionMode::Ccw, at, MOTION),
        730 | 810 | 820 | 830 | 850 | 890 => once(
            &mut w.motion,
            MotionMode::Cycle((g10 / 10) as u8),
            at,
            MOTION,
        ),
        800 => once(&mut w.motion, MotionMode::Off, at, MOTION),
        382..=385 => once(
            &mut w.motion,
            MotionMode::Probe(crate::probe::ProbeMove {
                toward: g10 <= 383,
                must_trip: g10.is_multiple_of(2),
            }),
            at,
            MOTION,
        ),
        40 => once(&mut w.non_modal, NonModal::Dwell, at, "a non-modal code"),
        100 => once(
            &mut w.non_modal,
            NonModal::SetWorkOffset,
            at,
            "a non-modal code",
        ),
        530 => once(
            &mut w.non_modal,
            NonModal::MachineCoords,
            at,
            "a non-modal code",
        ),
        920 => once(&mut w.non_modal, NonModal::G92Set, at, "a non-modal code"),
        921 => once(
            &mut w.non_modal,
            NonModal::G92Cancel,
            at,
            "a non-modal code",
        ),
        170 => once(&mut w.plane, Plane::G17, at, "the plane"),
        180 => once(&mut w.plane, Plane::G18, at, "the plane"),
        190 => once(&mut w.plane, Plane::G19, at, "the plane"),
        200 => once(&mut w.inches, true, at, "the units (G20/G21)"),
        210 => once(&mut w.inches, false, at, "the units (G20/G21)"),
        400 => once(&mut w.comp, CompSide::Off, at, "radius compensation"),
        410 => once(&mut w.comp, CompSide::Left, at, "radius compensation"),
        420 => once(&mut w.comp, CompSide::Right, at, "radius compensation"),
        430 => once(&mut w.length, true, at, "the tool length (G43/G49)"),
        490 => once(&mut w.length, false, at, "the tool length (G43/G49)"),
        540..=590 if g10.is_multiple_of(10) => once(
            &mut w.system,
            (g10 / 10 - 54) as usize,
            at,
            "the work offset",
        ),
        591..=593 => once(
            &mut w.system,
            (g10 - 591 + 6) as usize,
            at,
            "the work offset",
        ),
        610 => once(&mut w.path, PathMode::ExactPath, at, "path control"),
        611 => once(&mut w.path, PathMode::ExactStop, at, "path control"),
        640 => once(&mut w.path, PathMode::Blend, at, "path control"),
        900 => once(&mut w.absolute, true, at, "the distance mode (G90/G91)"),
        910 => once(&mut w.absolute, false, at, "the distance mode (G90/G91)"),
        901 => once(&mut w.arc_absolute, true, at, "the arc distance mode"),
        911 => once(&mut w.arc_absolute, false, at, "the arc distance mode"),
        930 => once(&mut w.feed_mode, FeedMode::InverseTime, at, "the feed mode"),
        940 => once(&mut w.feed_mode, FeedMode::PerMinute, at, "the feed mode"),
        950 => once(&mut w.feed_mode, FeedMode::PerRev, at, "the feed mode"),
        // G97: spindle speed in rpm, the only mode cncd's ISO dialect has (CAM posts write it).
        970 => Ok(()),
        980 => once(&mut w.retract_to_r, false, at, "the retract mode (G98/G99)"),
        990 => once(&mut w.retract_to_r, true, at, "the retract mode (G98/G99)"),
        _ => Err(unsupported(at, name)),
    }
}

/// The M code `m` into its group; `bound` says whether the machine binds it to I/O.
pub fn m_word(w: &mut Words, m: u16, at: usize, bound: bool) -> Result<(), Fail> {
    match m {
        0 | 1 | 2 | 30 => once(&mut w.stop, m, at, "a program stop (M0 M1 M2 M30)"),
        3..=5 => once(&mut w.spindle, m, at, "the spindle (M3 M4 M5)"),
        6 => {
            if w.m6.is_some() {
                return once(&mut Some(((), at)), (), at, "M6");
            }
            w.m6 = Some(at);
            Ok(())
        }
        7..=9 => {
            if w.coolant.iter().any(|(c, _)| *c == m || *c == 9 || m == 9) {
                return once(&mut Some(((), at)), (), at, "coolant (M7 M8 M9)");
            }
            w.coolant.push((m, at));
            Ok(())
        }
        _ if bound => {
            w.bound.push((m, at));
            Ok(())
        }
        _ => Err(unsupported(at, format!("M{m}"))),
    }
}

/// A letter word other than G, M, N: into its slot. `axis` is the machine axis the letter
/// names, if any.
pub fn letter(
    w: &mut Words,
    letter: u8,
    v: f64,
    at: usize,
    axis: Option<usize>,
) -> Result<(), Fail> {
    if let Some(k) = axis {
        return once(&mut w.axes[k], v, at, &format!("axis {}", letter as char));
    }
    let what = format!("{}", letter as char);
    let slot = match letter {
        b'I' => &mut w.i,
        b'J' => &mut w.j,
        b'K' => &mut w.k,
        b'R' => &mut w.r,
        b'P' => &mut w.p,
        b'Q' => &mut w.q,
        b'L' => &mut w.l,
        b'D' => &mut w.d,
        b'H' => &mut w.h,
        b'F' => &mut w.f,
        b'S' => &mut w.s,
        b'T' => &mut w.t,
        _ => return Err(unsupported(at, format!("the word {what}"))),
    };
    once(slot, v, at, &what)
}

/// A whole number from a word's value (G codes are read to a tenth).
pub fn whole(v: f64, at: usize, what: &str, max: f64) -> Result<u32, Fail> {
    let r = v.round();
    if !v.is_finite() || (v - r).abs() > 1e-4 || r < 0.0 || r > max {
        return Err(Fail::new(
            at,
            DiagCode::WordOutOfRange,
            format!("{what}{v} is not a whole number in 0..{max}"),
        ));
    }
    Ok(r as u32)
}

/// A G code's value in tenths (`59.1` → 591); other fractions are not G codes.
pub fn g_tenths(v: f64, at: usize) -> Result<u32, Fail> {
    let t = (v * 10.0).round();
    if !v.is_finite() || (v * 10.0 - t).abs() > 1e-3 || !(0.0..=9999.0).contains(&t) {
        return Err(unsupported(at, format!("G{v}")));
    }
    Ok(t as u32)
}

/// The words of a line that is read but not run (a skipped branch or subroutine body) and
/// are written as numbers: a word cncd does not run refuses the program wherever it stands,
/// so what validation accepts never meets it at run time.
pub fn check_unrun(
    l: &super::ast::Line,
    axis_letters: &[u8],
    bound: impl Fn(u16) -> bool,
) -> Result<(), Fail> {
    for word in &l.words {
        let super::ast::Expr::Num(v) = word.value else {
            continue;
        };
        let at = word.at;
        // Only whether the word is one cncd runs: group conflicts are for the run to find.
        let mut w = Words::default();
        match word.letter {
            b'G' => g_word(&mut w, g_tenths(v, at)?, at)?,
            b'M' => {
                let m = whole(v, at, "M", 999.0)? as u16;
                m_word(&mut w, m, at, bound(m))?
            }
            b'N' => {}
            letter => {
                let axis = axis_letters.iter().position(|&a| a == letter);
                self::letter(&mut w, letter, v, at, axis)?
            }
        }
    }
    Ok(())
}
