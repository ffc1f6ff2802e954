//! M functions (spindle direction, feed scale, gear range, outputs), feed F and spindle speed
//! S (SPEC §5, §6): their modal effect and the checks a feed move needs.

use super::collect::Words;
use super::modal::State;
use super::{Fail, Interpreter, fail};
use crate::block::{Feed, MCodes, Spindle, SpindleDir};
use crate::diag::DiagCode;
use crate::program::feed;
use crate::units::AxesMm;

impl Interpreter {
    /// M functions: spindle direction, feed scale, gear range (one of each per block).
    pub(super) fn m_functions(&self, w: &Words, st: &mut State) -> Result<MCodes, Fail> {
        let mut m_codes: MCodes = [None; 4];
        let (mut dir_at, mut scale_at, mut gear_at) = (None, None, None);
        st.modal.spindle.outputs = st.modal.spindle.outputs.carried();
        for (k, (m, at)) in w.m.iter().flatten().enumerate() {
            m_codes[k] = Some(*m);
            if self.m_outputs.apply(*m, &mut st.modal.spindle.outputs) {
                continue;
            }
            let gear = crate::kr::config::gear_for_m_code(&self.gears, *m);
            let (slot, what) = match m {
                3..=5 => (&mut dir_at, "spindle direction (M3/M4/M5)"),
                36 | 37 => (&mut scale_at, "feed scale (M36/M37)"),
                _ if gear.is_some() => (&mut gear_at, "gear range"),
                41..=44 => {
                    return fail(
                        *at,
                        DiagCode::GearNotConfigured,
                        format!(
                            "M{m} selects no gear range: the machine's [kr.gears] table has no \
                             range with m_code = {m}"
                        ),
                    );
                }
                _ => continue,
            };
            if slot.is_some() {
                return fail(
                    *at,
                    DiagCode::MGroupConflict,
                    format!("two M functions for the {what} in one block"),
                );
            }
            *slot = Some(*m);
            match m {
                3 => st.modal.spindle.dir = SpindleDir::Cw,
                4 => st.modal.spindle.dir = SpindleDir::Ccw,
                5 => st.modal.spindle.dir = SpindleDir::Stopped,
                36 => st.modal.m37 = false,
                37 => st.modal.m37 = true,
                _ => st.modal.spindle.gear = gear.unwrap_or(0),
            }
        }
        if crate::block::ends_program(&m_codes) {
            // M2/M30 end the program: the spindle stops with it (the next run starts from the
            // power-on modal state anyway, docs/language.md).
            st.modal.spindle.dir = SpindleDir::Stopped;
            // … and so do the outputs it switched on (LinuxCNC: M2/M30 switch coolant off).
            st.modal.spindle.outputs.on = 0;
        }
        // P of the range in force (gear 0, none selected yet, is range 1), for feed per rev.
        st.modal.spindle.gear_max_rpm = self
            .gears
            .get(usize::from(st.modal.spindle.gear.max(1)) - 1)
            .map_or(0.0, |g| g.max_rpm);
        Ok(m_codes)
    }

    /// Feed group, F, and S / G76 S / constant cutting speed (SPEC §5, §6). Returns whether
    /// the feed is per revolution.
    pub(super) fn feed_and_speed(
        &self,
        w: &Words,
        old: &State,
        st: &mut State,
    ) -> Result<bool, Fail> {
        let css_swapped = self.rules.css_swapped;
        if let Some((fm, _)) = w.feed_mode {
            st.modal.feed_mode = fm;
        }
        let per_rev = st.modal.feed_mode.per_rev(css_swapped);
        if per_rev != old.modal.feed_mode.per_rev(css_swapped) {
            // F is not carried over between per minute and per revolution (seed 002 §6.1).
            st.modal.feed = None;
        }
        if let Some((f, at)) = w.f {
            st.modal.feed =
                Some(feed::convert(f, per_rev).map_err(|e| Fail::new(at, e.code(), e))?);
        }
        st.modal.spindle.css = st.modal.feed_mode.css();
        if let Some(at) = w.g76 {
            let Some((s, s_at)) = w.s else {
                return fail(
                    at,
                    DiagCode::G76NeedsS,
                    "G76 needs S: the spindle speed limit in rpm (G76 S2000)",
                );
            };
            if s.value < 0.0 {
                return fail(
                    s_at,
                    DiagCode::NegativeSpeed,
                    "the spindle speed limit cannot be negative",
                );
            }
            st.modal.spindle.limit_rpm = s.value;
        } else if let Some((s, at)) = w.s {
            if s.value < 0.0 {
                return fail(at, DiagCode::NegativeSpeed, "S cannot be negative");
            }
            st.modal.spindle.s = s.value;
            st.modal.speed_from_css = false;
        } else if old.modal.spindle.css && !st.modal.spindle.css {
            // KŘR ends without S: the last reached speed becomes S, known only at run time.
            st.modal.spindle.s = 0.0;
            st.modal.speed_from_css = true;
        }
        Ok(per_rev)
    }

    /// The programmed feed as the feed along the block's whole axis vector (rotary axes in
    /// degrees), by the rule of [`feed::rotary_feed_factor`] (docs/lathe.md).
    pub(super) fn rotary_feed(&self, f: Feed, start: AxesMm, end: AxesMm) -> Feed {
        if self.moving_rotary_axis(start, end).is_none() {
            return f;
        }
        let n = self.n_axes;
        let k = feed::rotary_feed_factor(&start.0[..n], &end.0[..n], &self.rotary_kppr[..n]);
        match f {
            Feed::MmPerMin(v) => Feed::MmPerMin(v * k),
            Feed::MmPerRev(v) => Feed::MmPerRev(v * k),
        }
    }

    /// SPEC §5: βmax = Vmax/S. A feed per revolution above it cannot be followed at the
    /// nominal spindle speed of the block (the axes cap the feed): a warning.
    pub(super) fn beta_max_warning(&self, beta_mm_rev: f64, spindle: &Spindle) -> Option<String> {
        let n = spindle.per_rev_nominal_rpm()?;
        let beta_max = crate::kr::max_feed_mm_rev(self.max_feed_mm_min, n)?;
        (self.max_feed_mm_min > 0.0 && beta_mm_rev > beta_max + 1e-9).then(|| {
            format!(
                "feed {beta_mm_rev} mm/rev is above βmax = {beta_max:.3} mm/rev (Vmax {} mm/min \
                 / {n} rpm; at this feed Smax = Vmax/β = {:.0} rpm): the axes limit the feed, \
                 it will not follow the spindle",
                self.max_feed_mm_min,
                self.max_feed_mm_min / beta_mm_rev
            )
        })
    }
}

/// A feed move needs F > 0 in the feed mode in force, and feed per revolution a turning
/// spindle (SPEC §5).
pub(super) fn check_feed(w: &Words, st: &State, old: &State, per_rev: bool) -> Result<(), Fail> {
    match st.modal.feed {
        Some(f) if feed_value(f) > 0.0 => {}
        Some(_) => {
            return fail(
                w.f.map_or(w.first, |f| f.1),
                DiagCode::FeedZero,
                "feed F is zero: a feed move needs F > 0",
            );
        }
        None if old.modal.feed.is_some() => {
            return fail(
                w.first,
                DiagCode::FeedModeChanged,
                "the feed changed between per minute and per revolution: program F again",
            );
        }
        None => {
            return fail(
                w.first,
                DiagCode::NoFeed,
                "no feed: program F before the first feed move (G1/G2/G3)",
            );
        }
    }
    if per_rev
        && (st.modal.spindle.dir == SpindleDir::Stopped
            || (st.modal.spindle.s <= 0.0 && !st.modal.speed_from_css))
    {
        return fail(
            w.first,
            DiagCode::FeedPerRevWithoutSpindle,
            "feed per revolution needs a turning spindle: program S and M3 or M4 first",
        );
    }
    Ok(())
}

fn feed_value(f: Feed) -> f64 {
    match f {
        Feed::MmPerMin(v) | Feed::MmPerRev(v) => v,
    }
}
