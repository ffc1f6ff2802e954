//! The dry run (issue #48): a program's interpreted motion without a machine, one [`Move`]
//! per motion block or dwell, the same blocks validation, preview and the planner see.
//! Nothing persistent changes (a `G10` acts within the run only). `cncctl interpret --json`
//! prints [`Move::json`] per line.

use super::{Setup, stream};
use crate::block::{ArcDir, BlockKind, Feed, Path, Plane};
use crate::diag::Diagnostic;
use crate::units::AxesMm;

/// What a move is.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum MoveKind {
    Rapid,
    Feed,
    Arc {
        /// Centre in machine coordinates (the two plane components are meaningful).
        centre: AxesMm,
        plane: Plane,
        dir: ArcDir,
    },
    Dwell {
        seconds: f64,
    },
}

/// One interpreted move: where it ends (machine coordinates, mm; degrees on a rotary axis).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Move {
    pub kind: MoveKind,
    pub end: AxesMm,
    /// Path feed, mm/min (`None` for rapids and dwells, and for feed per revolution).
    pub feed_mm_min: Option<f64>,
    /// Feed per revolution, mm (G95), when that is the feed.
    pub feed_mm_rev: Option<f64>,
    /// Block index (0-based), programmed N, 1-based source line.
    pub seq: u32,
    pub n: Option<u32>,
    pub line: u32,
}

/// The moves of `text`, and every message; stops at the first error (the moves before it are
/// kept: they show how far the program reads).
pub fn moves(text: &str, setup: &Setup) -> (Vec<Move>, Vec<Diagnostic>) {
    let mut out = Vec::new();
    let mut diags = Vec::new();
    let mut s = stream(text, setup);
    let mut last_end = setup.start;
    while let Some(item) = s.next() {
        diags.extend(s.take_notes());
        match item {
            Ok(b) => {
                let (feed_mm_min, feed_mm_rev) = match b.feed {
                    Feed::MmPerMin(f) => (Some(f), None),
                    Feed::MmPerRev(f) => (None, Some(f)),
                };
                let (kind, end) = match b.kind {
                    BlockKind::Motion { end, path, .. } => {
                        let kind = match path {
                            Path::Rapid => MoveKind::Rapid,
                            Path::Line | Path::Probe(_) => MoveKind::Feed,
                            Path::Arc { dir, center, plane } => MoveKind::Arc {
                                centre: center,
                                plane,
                                dir,
                            },
                        };
                        (kind, end)
                    }
                    BlockKind::Dwell { seconds } => (MoveKind::Dwell { seconds }, last_end),
                    _ => continue,
                };
                last_end = end;
                let moving = !matches!(kind, MoveKind::Rapid | MoveKind::Dwell { .. });
                out.push(Move {
                    kind,
                    end,
                    feed_mm_min: feed_mm_min.filter(|_| moving),
                    feed_mm_rev: feed_mm_rev.filter(|_| moving),
                    seq: b.seq,
                    n: b.n,
                    line: b.line,
                });
            }
            Err(d) => {
                diags.push(d);
                break;
            }
        }
    }
    diags.extend(s.take_notes());
    (out, diags)
}

impl Move {
    /// One JSON object: `kind` (rapid, feed, arc, dwell), `end` per axis, for arcs `centre`
    /// (the plane's two axes), `plane` (G17..G19) and `dir` (cw, ccw), `feed_mm_min` (or
    /// `feed_mm_rev`), `seconds` of a dwell, `seq`, `n`, `line`.
    pub fn json(&self, axis_names: &[char]) -> String {
        let axes = |p: &AxesMm, only: Option<(usize, usize)>| {
            let mut s = String::from("{");
            for (k, a) in axis_names.iter().enumerate().take(crate::units::MAX_AXES) {
                if only.is_some_and(|(i, j)| k != i && k != j) {
                    continue;
                }
                if s.len() > 1 {
                    s.push(',');
                }
                s.push_str(&format!("\"{a}\":{}", num(p[k])));
            }
            s.push('}');
            s
        };
        let kind = match self.kind {
            MoveKind::Rapid => "rapid",
            MoveKind::Feed => "feed",
            MoveKind::Arc { .. } => "arc",
            MoveKind::Dwell { .. } => "dwell",
        };
        let mut s = format!("{{\"kind\":\"{kind}\",\"end\":{}", axes(&self.end, None));
        match self.kind {
            MoveKind::Arc { centre, plane, dir } => {
                let name = match plane {
                    Plane::G17 => "G17",
                    Plane::G18 => "G18",
                    Plane::G19 => "G19",
                };
                let dir = if dir == ArcDir::Cw { "cw" } else { "ccw" };
                s.push_str(&format!(
                    ",\"centre\":{},\"plane\":\"{name}\",\"dir\":\"{dir}\"",
                    axes(&centre, Some(plane.axes()))
                ));
            }
            MoveKind::Dwell { seconds } => s.push_str(&format!(",\"seconds\":{}", num(seconds))),
            _ => {}
        }
        if let Some(f) = self.feed_mm_min {
            s.push_str(&format!(",\"feed_mm_min\":{}", num(f)));
        }
        if let Some(f) = self.feed_mm_rev {
            s.push_str(&format!(",\"feed_mm_rev\":{}", num(f)));
        }
        let n = self.n.map_or("null".to_string(), |n| n.to_string());
        s.push_str(&format!(
            ",\"seq\":{},\"n\":{n},\"line\":{}}}",
            self.seq, self.line
        ));
        s
    }
}

/// A JSON number: finite values as Rust prints them (shortest round-trip), others null.
fn num(v: f64) -> String {
    if v.is_finite() {
        let v = if v == 0.0 { 0.0 } else { v };
        format!("{v}")
    } else {
        "null".to_string()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn cnc836_moves_as_json() {
        let setup = Setup::new(&['X', 'Y', 'Z']);
        let (m, d) = moves("G1 X10 F100\nG2 X20 I5 J0\n", &setup);
        assert!(d.is_empty(), "{d:?}");
        assert_eq!(m.len(), 2);
        assert_eq!(
            m[0].json(&['X', 'Y', 'Z']),
            r#"{"kind":"feed","end":{"X":10,"Y":0,"Z":0},"feed_mm_min":100,"seq":0,"n":null,"line":1}"#
        );
        assert!(
            m[1].json(&['X', 'Y', 'Z'])
                .contains(r#""centre":{"X":15,"Y":0},"plane":"G17","dir":"cw""#)
        );
    }
}
