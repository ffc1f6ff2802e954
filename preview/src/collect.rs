//! What the program preview gathers from the stages for one page (SPEC §7.5): programmed path,
//! compensated path, and the planner's classification of every junction.

use kernel::block::Block;
use kernel::comp::{CompBlock, Role};
use kernel::plan::{Junction, SegPath, Segment};

use crate::decimate::{DotSet, JunctionDot, Track};
use crate::paging::Page;
use crate::pipeline::Sink;
use crate::plane::{Projection, block_path};
use crate::{RedJunction, RedKind};

/// Points kept per track and dots kept before merging (bounded memory, see [`crate::decimate`]).
const TRACK_BUDGET: usize = 1 << 17;
const DOT_BUDGET: usize = 1 << 16;

/// Bounding box in plane coordinates.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Bounds {
    pub min: [f64; 2],
    pub max: [f64; 2],
}

impl Bounds {
    pub const EMPTY: Bounds = Bounds {
        min: [f64::INFINITY; 2],
        max: [f64::NEG_INFINITY; 2],
    };

    pub fn add(&mut self, p: [f64; 2]) {
        for (i, v) in p.into_iter().enumerate() {
            self.min[i] = self.min[i].min(v);
            self.max[i] = self.max[i].max(v);
        }
    }

    pub fn is_empty(&self) -> bool {
        self.min[0] > self.max[0]
    }
}

/// The preview's sink.
pub struct Collector {
    proj: Projection,
    page: Page,
    max_listed: usize,
    pub feed: Track,
    pub rapid: Track,
    pub comp: Track,
    pub dots: DotSet,
    pub bounds: Bounds,
    pub smooth: u64,
    pub red: u64,
    pub red_list: Vec<RedJunction>,
    /// A tool-centre block on this page differs from the programmed path (G41/G42 in force).
    pub compensated: bool,
    centre: ToolCentre,
    done: bool,
    scratch: Vec<[f64; 2]>,
}

impl Collector {
    pub fn new(proj: Projection, page: Page, max_listed: usize) -> Self {
        Collector {
            proj,
            page,
            max_listed,
            feed: Track::new(TRACK_BUDGET),
            rapid: Track::new(TRACK_BUDGET),
            comp: Track::new(TRACK_BUDGET),
            dots: DotSet::new(DOT_BUDGET),
            bounds: Bounds::EMPTY,
            smooth: 0,
            red: 0,
            red_list: Vec::new(),
            compensated: false,
            centre: ToolCentre::default(),
            done: false,
            scratch: Vec::new(),
        }
    }

    fn draw(&mut self, path: &SegPath, which: Which) {
        let track = match which {
            Which::Feed => &mut self.feed,
            Which::Rapid => &mut self.rapid,
            Which::Comp => &mut self.comp,
        };
        // Flatten arcs to half the track's current cell: finer is lost on decimation anyway.
        self.proj
            .flatten(path, track.cell() / 2.0, &mut self.scratch);
        let from = self.proj.point(&path.start());
        self.bounds.add(from);
        for p in &self.scratch {
            self.bounds.add(*p);
        }
        track.segment(from, &self.scratch);
    }
}

#[derive(Clone, Copy)]
enum Which {
    Feed,
    Rapid,
    Comp,
}

impl Sink for Collector {
    fn programmed(&mut self, b: &Block) {
        if !self.page.contains(b.seq) {
            return;
        }
        if let Some((path, rapid)) = block_path(b) {
            self.draw(&path, if rapid { Which::Rapid } else { Which::Feed });
        }
    }

    fn compensated(&mut self, c: &CompBlock) {
        let part = self.centre.next(c);
        if !part.drawn() || !self.page.contains(c.block.seq) {
            if part != CentrePart::Compensated {
                self.comp.pen_up();
            }
            return;
        }
        if let Some((path, _)) = block_path(&c.block) {
            self.compensated = true;
            self.draw(&path, Which::Comp);
        }
    }

    fn segment(&mut self, s: &Segment) {
        if s.seq >= self.page.end {
            self.done = true;
            return;
        }
        // The end of the program is not a junction.
        if s.seq < self.page.first || s.last {
            return;
        }
        let at = self.proj.point(&s.path.end());
        let red = s.junction.is_red();
        self.bounds.add(at);
        let label = red.then(|| block_label(s.n, s.line));
        if red {
            self.red += 1;
            if self.red_list.len() < self.max_listed {
                self.red_list.push(RedJunction {
                    seq: s.seq,
                    n: s.n,
                    line: s.line,
                    at,
                    kind: if s.junction == Junction::Stop {
                        RedKind::Stop
                    } else {
                        RedKind::SpeedDrop
                    },
                    v_mm_s: s.v_end_mm_s,
                    feed_mm_s: s.feed_mm_s,
                });
            }
        } else {
            self.smooth += 1;
        }
        self.dots.add(JunctionDot {
            at,
            red,
            count: 1,
            label,
        });
    }

    fn done(&self) -> bool {
        self.done
    }
}

/// What a tool-centre block is to the tool-centre path a preview draws (SPEC §4.2).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum CentrePart {
    /// Compensated (G41/G42 in force).
    Compensated,
    /// The first pass-through block after compensated ones: the cancel move starts from the
    /// tool centre, so it is part of the path too.
    Leave,
    /// Neither: the path has a gap here.
    Off,
}

impl CentrePart {
    /// Part of the drawn tool-centre path.
    pub fn drawn(self) -> bool {
        self != CentrePart::Off
    }
}

/// Follows the compensator's blocks in order to tell which belong to the tool-centre path
/// (the rule of every preview sink: the paged picture and the outline).
#[derive(Clone, Copy, Debug, Default)]
pub struct ToolCentre {
    /// Last block was compensated (the next pass-through one is the leave move).
    prev_comp: bool,
}

impl ToolCentre {
    /// What the next tool-centre block `c` is to the path.
    pub fn next(&mut self, c: &CompBlock) -> CentrePart {
        let comp = c.role != Role::Passthrough;
        let leave = !comp && self.prev_comp;
        self.prev_comp = comp;
        if comp {
            CentrePart::Compensated
        } else if leave {
            CentrePart::Leave
        } else {
            CentrePart::Off
        }
    }
}

/// `N40`, or `line 12` for a block without a number.
pub fn block_label(n: Option<u32>, line: u32) -> String {
    match n {
        Some(n) => format!("N{n}"),
        None => format!("line {line}"),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::PreviewOptions;
    use kernel::program::Setup;

    /// What each tool-centre block is to the path, by its `N` number.
    struct Parts(ToolCentre, Vec<(Option<u32>, CentrePart)>);

    impl Sink for Parts {
        fn compensated(&mut self, c: &CompBlock) {
            let part = self.0.next(c);
            self.1.push((c.block.n, part));
        }
        fn segment(&mut self, _s: &Segment) {}
    }

    #[test]
    fn the_tool_centre_path_is_the_compensated_blocks_and_the_leave_move() {
        let text = "N1 G92 D1 R0=2\nN2 G17 D1\nN3 G0 X-10 Y-10\nN4 G41 G1 X0 Y0 F600\n\
                    N5 Y10\nN6 X10\nN7 G40 G1 X20 Y-10\nN8 X30\nN9 Y-20\n";
        let opts = PreviewOptions::new(Setup::new(&['X', 'Y', 'Z']));
        let mut parts = Parts(ToolCentre::default(), Vec::new());
        crate::pipeline::run(text, &opts, &mut parts).expect("valid");
        let of = |n: u32| -> Vec<CentrePart> {
            parts
                .1
                .iter()
                .filter(|p| p.0 == Some(n))
                .map(|p| p.1)
                .collect()
        };
        assert!(of(3).iter().all(|&p| p == CentrePart::Off), "{:?}", parts.1);
        for n in 4..=6 {
            assert!(!of(n).is_empty(), "N{n}: {:?}", parts.1);
            assert!(
                of(n).iter().all(|&p| p == CentrePart::Compensated),
                "N{n}: {:?}",
                parts.1
            );
        }
        assert_eq!(
            of(7),
            [CentrePart::Leave],
            "the cancel move starts at the tool centre"
        );
        assert_eq!(of(8), [CentrePart::Off]);
        assert_eq!(of(9), [CentrePart::Off]);
        assert!(CentrePart::Leave.drawn() && !CentrePart::Off.drawn());
    }
}
