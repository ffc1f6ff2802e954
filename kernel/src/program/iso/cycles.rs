//! Canned cycles G73, G81, G82, G83, G85, G89 with G98/G99 and L repeats, as LinuxCNC 2.9
//! runs them (RS274-NGC; its interp_cycles): in the selected plane, drilling along the third
//! axis. Each hole: rapid in the plane at the clear level, rapid down to R, the cycle's own
//! moves, then the retract to R (G99) or to the initial level (G98). The moves are ordinary
//! blocks of the line, so everything after the interpreter sees plain lines and dwells.

use super::Fail;
use super::exec::Exec;
use super::motion::third_axis;
use super::state::{CompSide, FeedMode};
use super::words::Words;
use crate::block::{BlockKind, Feed, Path};
use crate::diag::DiagCode;

/// How far a peck (G73, G83) backs off before feeding on: LinuxCNC 2.9's 0.010 inch.
pub const PECK_CLEARANCE_MM: f64 = 0.254;

/// Most holes one cycle line may make (L).
pub const MAX_REPEATS: f64 = 10_000.0;
/// Pecks (G73, G83) of one block at most, over all its holes: a block's moves are made at
/// once, and a micrometre's peck down a metre would be a million of them (or never end, when
/// the peck is below the depth's rounding).
pub const MAX_PECKS: f64 = 100_000.0;

/// The cycle's words resolved for this line (program coordinates of the plane's axes and
/// of the third axis, mm).
struct Holes {
    /// First and second plane coordinates of the first hole, and the step per repeat (G91).
    aa: f64,
    bb: f64,
    step: (f64, f64),
    r: f64,
    bottom: f64,
    clear: f64,
    repeats: u32,
    p_s: f64,
    q_mm: f64,
}

fn cycle_fail<T>(at: usize, m: impl ToString) -> Result<T, Fail> {
    Err(Fail::new(at, DiagCode::CycleWord, m))
}

impl Exec<'_> {
    /// A cycle line: its holes.
    pub fn cycle(&mut self, w: &Words, g: u8) -> Result<(), Fail> {
        if self.st.feed_mode == FeedMode::InverseTime {
            return cycle_fail(
                w.first,
                "canned cycles cannot run with inverse time feed (G93)",
            );
        }
        if self.st.comp != CompSide::Off {
            return cycle_fail(
                w.first,
                "canned cycles cannot run with radius compensation on (G41/G42)",
            );
        }
        self.feed_for(w.first, 1.0)?;
        let h = self.holes(w, g)?;
        let (a, b) = self.st.plane.axes();
        let c = third_axis(self.st.plane);
        let mut current_c = self.st.program_pos()[c];
        if current_c < h.r {
            // Below the R plane: straight up to it first.
            let pos = self.st.program_pos();
            self.traverse(pos[a], pos[b], h.r);
            current_c = h.r;
        }
        let (mut aa, mut bb) = (h.aa, h.bb);
        for k in 0..h.repeats {
            aa += h.step.0;
            bb += h.step.1;
            if k == 0 && current_c > h.r {
                self.traverse(aa, bb, current_c);
                self.traverse(aa, bb, h.r);
            } else {
                self.traverse(aa, bb, h.clear);
                if h.clear > h.r {
                    self.traverse(aa, bb, h.r);
                }
            }
            self.hole(g, &h, aa, bb)?;
        }
        Ok(())
    }

    /// One hole at (aa, bb), starting at R.
    fn hole(&mut self, g: u8, h: &Holes, aa: f64, bb: f64) -> Result<(), Fail> {
        match g {
            81 => {
                self.cut(aa, bb, h.bottom)?;
                self.traverse(aa, bb, h.clear);
            }
            82 | 89 => {
                self.cut(aa, bb, h.bottom)?;
                self.emit(
                    BlockKind::Dwell { seconds: h.p_s },
                    Feed::default(),
                    [None; 4],
                );
                if g == 82 {
                    self.traverse(aa, bb, h.clear);
                } else {
                    self.cut(aa, bb, h.clear)?;
                }
            }
            85 => {
                self.cut(aa, bb, h.bottom)?;
                self.cut(aa, bb, h.r)?;
                self.traverse(aa, bb, h.clear);
            }
            _ => {
                let mut depth = h.r - h.q_mm;
                // (Bounded also where the peck is below the depth's rounding.)
                let mut left = MAX_PECKS as u32;
                while depth > h.bottom && left > 0 {
                    left -= 1;
                    self.cut(aa, bb, depth)?;
                    if g == 83 {
                        self.traverse(aa, bb, h.r);
                    }
                    self.traverse(aa, bb, depth + PECK_CLEARANCE_MM);
                    depth -= h.q_mm;
                }
                self.cut(aa, bb, h.bottom)?;
                self.traverse(aa, bb, h.clear);
            }
        }
        Ok(())
    }

    /// R, Z (bottom), P, Q and L of the line or remembered from the cycle's earlier lines
    /// (LinuxCNC: R and Z may be left out only while the same cycle stays in force).
    fn holes(&mut self, w: &Words, g: u8) -> Result<Holes, Fail> {
        let same_cycle = self.prev_motion == self.st.motion;
        let (a, b) = self.st.plane.axes();
        let c = third_axis(self.st.plane);
        let pos = self.st.program_pos();
        let r_word = match (w.r, self.st.cycle.r_mm) {
            (Some((r, _)), _) => self.st.mm(r),
            (None, Some(r)) if same_cycle => r,
            _ => return cycle_fail(w.first, format!("G{g} needs R: the retract plane")),
        };
        let z_word = match (w.axes[c], self.st.cycle.bottom_mm) {
            (Some((z, _)), _) => self.st.mm(z),
            (None, Some(z)) if same_cycle => z,
            _ => {
                return cycle_fail(
                    w.first,
                    format!("G{g} needs the depth (the third axis's word)"),
                );
            }
        };
        let initial = *self.st.cycle.initial_mm.get_or_insert(pos[c]);
        let word = |k: usize| w.axes[k].map(|x| self.st.mm(x.0));
        // G90: X Y R Z are coordinates; G91: X Y are steps per hole, R is from the initial
        // level and Z from R.
        let (aa, bb, step, r, bottom) = if self.st.absolute {
            let (aa, bb) = (word(a).unwrap_or(pos[a]), word(b).unwrap_or(pos[b]));
            (aa, bb, (0.0, 0.0), r_word, z_word)
        } else {
            let step = (word(a).unwrap_or(0.0), word(b).unwrap_or(0.0));
            let r = r_word + initial;
            (pos[a], pos[b], step, r, r + z_word)
        };
        if r < bottom {
            return cycle_fail(
                w.first,
                format!("G{g}: R ({r:.4} mm) is below the depth ({bottom:.4} mm)"),
            );
        }
        let p_s = self.cycle_p(w, g, same_cycle)?;
        let q_mm = self.cycle_q(w, g, same_cycle)?;
        let repeats = match w.l {
            None => 1,
            Some((l, at)) => {
                if l.fract() != 0.0 || !(1.0..=MAX_REPEATS).contains(&l) {
                    return cycle_fail(at, format!("L{l}: a cycle repeats 1..{MAX_REPEATS} times"));
                }
                l as u32
            }
        };
        let pecks = ((r - bottom) / q_mm).ceil() * f64::from(repeats);
        if matches!(g, 73 | 83) && (pecks.is_nan() || pecks > MAX_PECKS) {
            return cycle_fail(
                w.q.map_or(w.first, |x| x.1),
                format!(
                    "G{g}: {pecks} pecks of {q_mm} mm in one block, at most {MAX_PECKS}: a larger Q"
                ),
            );
        }
        let clear = if self.st.retract_to_r {
            r
        } else {
            initial.max(r)
        };
        self.st.cycle.r_mm = Some(r_word);
        self.st.cycle.bottom_mm = Some(z_word);
        Ok(Holes {
            aa,
            bb,
            step,
            r,
            bottom,
            clear,
            repeats,
            p_s,
            q_mm,
        })
    }

    fn cycle_p(&mut self, w: &Words, g: u8, same_cycle: bool) -> Result<f64, Fail> {
        if !matches!(g, 82 | 89) {
            return Ok(0.0);
        }
        match (w.p, self.st.cycle.p_s) {
            (Some((p, at)), _) => {
                if !p.is_finite() || p < 0.0 {
                    return cycle_fail(at, format!("P{p}: the dwell cannot be negative"));
                }
                self.st.cycle.p_s = Some(p);
                Ok(p)
            }
            (None, Some(p)) if same_cycle => Ok(p),
            _ => cycle_fail(
                w.first,
                format!("G{g} needs P: the dwell at the bottom in seconds"),
            ),
        }
    }

    fn cycle_q(&mut self, w: &Words, g: u8, same_cycle: bool) -> Result<f64, Fail> {
        if !matches!(g, 73 | 83) {
            return Ok(0.0);
        }
        let q = match (w.q, self.st.cycle.q_mm) {
            (Some((q, _)), _) => self.st.mm(q),
            (None, Some(q)) if same_cycle => q,
            _ => return cycle_fail(w.first, format!("G{g} needs Q: the depth of each peck")),
        };
        if q.is_nan() || q <= 0.0 {
            return cycle_fail(w.q.map_or(w.first, |x| x.1), "Q must be greater than 0");
        }
        self.st.cycle.q_mm = Some(q);
        Ok(q)
    }

    /// The plane coordinates (aa, bb) and third-axis `cc` in program coordinates → machine.
    fn cycle_point(&self, aa: f64, bb: f64, cc: f64) -> crate::units::AxesMm {
        let (a, b) = self.st.plane.axes();
        let c = third_axis(self.st.plane);
        let off = self.st.offset();
        let mut p = self.st.machine;
        p[a] = aa + off[a];
        p[b] = bb + off[b];
        p[c] = cc + off[c];
        p
    }

    fn traverse(&mut self, aa: f64, bb: f64, cc: f64) {
        let start = self.st.machine;
        let end = self.cycle_point(aa, bb, cc);
        self.emit(
            BlockKind::Motion {
                start,
                end,
                path: Path::Rapid,
            },
            Feed::default(),
            [None; 4],
        );
    }

    fn cut(&mut self, aa: f64, bb: f64, cc: f64) -> Result<(), Fail> {
        let start = self.st.machine;
        let end = self.cycle_point(aa, bb, cc);
        let feed = self.feed_for(0, (end - start).norm(self.m.n_axes))?;
        self.emit(
            BlockKind::Motion {
                start,
                end,
                path: Path::Line,
            },
            feed,
            [None; 4],
        );
        Ok(())
    }
}
