//! The ISO state handed on as the kernel's [`Modal`] (what MDI after a program inherits, what
//! observers see) and taken back from one: motion, plane, G90/G91, feed mode and F,
//! continuity and the spindle. Units, work offsets, tools and cycles end with the run.

use super::state::{FeedMode, MotionMode, State};
use crate::block::Feed;
use crate::program::cnc836::{Modal, ModalParts, Motion};
use crate::program::feed::FeedMode as KernelFeedMode;

/// The kernel's modal state of `st`.
pub fn modal_of(st: &State) -> Modal {
    let motion = match st.motion {
        MotionMode::Line => Motion::Line,
        MotionMode::Cw => Motion::Cw,
        MotionMode::Ccw => Motion::Ccw,
        _ => Motion::Rapid,
    };
    let (feed_mode, feed) = match st.feed_mode {
        FeedMode::PerRev => (KernelFeedMode::G95, st.feed.map(Feed::MmPerRev)),
        FeedMode::PerMinute => (KernelFeedMode::G94, st.feed.map(Feed::MmPerMin)),
        FeedMode::InverseTime => (KernelFeedMode::G94, None),
    };
    Modal::from_parts(ModalParts {
        motion,
        plane: st.plane,
        absolute: st.absolute,
        feed_mode,
        feed,
        continuity: st.continuity,
        spindle: st.spindle,
        ..ModalParts::default()
    })
}

/// `st` continuing from an inherited modal state (MDI after a program or an MDI).
pub fn inherit(st: &mut State, m: &Modal) {
    let p = m.parts();
    st.motion = match p.motion {
        Motion::Rapid => MotionMode::Rapid,
        Motion::Line => MotionMode::Line,
        Motion::Cw => MotionMode::Cw,
        Motion::Ccw => MotionMode::Ccw,
    };
    st.plane = p.plane;
    st.absolute = p.absolute;
    st.continuity = p.continuity;
    st.spindle = p.spindle;
    st.spindle.length_offset_mm = 0.0;
    (st.feed_mode, st.feed) = match p.feed {
        Some(Feed::MmPerRev(f)) => (FeedMode::PerRev, Some(f)),
        Some(Feed::MmPerMin(f)) => (FeedMode::PerMinute, Some(f)),
        None if p.feed_mode.per_rev(false) => (FeedMode::PerRev, None),
        None => (FeedMode::PerMinute, None),
    };
}
