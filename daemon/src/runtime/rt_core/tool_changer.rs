//! Phase *automatic tool change* (docs/setup.md "Automatic tool changer"): while the program
//! is held at rest at an M6, the core puts the tool number on its outputs and runs the
//! configured steps one after another (each an M function's outputs, then its inputs waited
//! for), then resumes the program itself. It runs here rather than as program blocks because
//! the planner merges consecutive technology blocks: only the RT tick can run the steps in
//! order and wait for each confirmation.

use hal::io::IoBits;
use kernel::outputs::MFunction;

use super::RtCore;

/// Most steps a sequence may have (the configuration refuses more).
pub const MAX_STEPS: usize = 8;

/// The changer as the core takes it at construction: fixed size, `Copy` (no allocation in the
/// tick). `len == 0`: manual tool change (M6 holds for the operator).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct ToolChanger {
    /// The steps: each the M function the program's M code uses (bit k: output or input k).
    pub steps: [MFunction; MAX_STEPS],
    pub len: u8,
    /// Outputs carrying the tool number in binary: entry i is the output of bit i.
    pub number_outputs: [u8; 8],
    pub number_len: u8,
}

impl ToolChanger {
    /// Automatic mode: M6 runs the steps.
    pub fn automatic(&self) -> bool {
        self.len > 0
    }

    fn steps(&self) -> &[MFunction] {
        &self.steps[..usize::from(self.len).min(MAX_STEPS)]
    }

    fn number_outputs(&self) -> &[u8] {
        &self.number_outputs[..usize::from(self.number_len).min(8)]
    }

    /// The tool number outputs.
    fn number_mask(&self) -> u64 {
        self.number_outputs()
            .iter()
            .fold(0u64, |m, &k| m | 1u64 << (k % 64))
    }

    /// The outputs the changer drives: the tool number and every step's on/off. The program's
    /// M functions no longer switch them (the changer's state must not be undone by them).
    pub fn owned(&self) -> u64 {
        let number = self.number_mask();
        self.steps().iter().fold(number, |m, s| m | s.on | s.off)
    }

    /// The tool number outputs' values for `tool` (bits beyond them are dropped: the program
    /// check `tool_number_beyond_outputs` refused such a tool already).
    fn number_bits(&self, tool: u8) -> u64 {
        self.number_outputs()
            .iter()
            .enumerate()
            .filter(|(bit, _)| tool & (1 << bit) != 0)
            .fold(0, |m, (_, &k)| m | 1u64 << (k % 64))
    }
}

/// The changer's state between ticks.
#[derive(Clone, Copy, Debug, Default)]
pub(super) struct ChangerRun {
    pub(super) cfg: ToolChanger,
    /// [`ToolChanger::owned`], once.
    pub(super) owned: u64,
    /// A change is under way: index of the step whose inputs are waited for.
    pub(super) step: Option<u8>,
    /// 4 ms steps the current wait has lasted; `timed_out`: held until Resume.
    wait_steps: u32,
    timed_out: bool,
    /// The outputs the changer holds on (kept until the next change).
    pub(super) on: u64,
}

impl ChangerRun {
    pub(super) fn new(cfg: ToolChanger) -> ChangerRun {
        ChangerRun {
            cfg,
            owned: cfg.owned(),
            ..ChangerRun::default()
        }
    }

    /// A change runs now (the manual prompt is not shown).
    pub(super) fn running(&self) -> bool {
        self.step.is_some()
    }

    /// A wait of the change timed out: the machine holds until Resume.
    pub(super) fn timed_out(&self) -> bool {
        self.running() && self.timed_out
    }

    /// The change is over.
    fn end(&mut self) {
        self.step = None;
        self.timed_out = false;
        self.wait_steps = 0;
    }

    /// Stop or fault: the change ends where it is (nothing resumes by itself) and its outputs
    /// fall: the next job must not switch on what a broken-off change left.
    pub(super) fn abort(&mut self) {
        self.end();
        self.on = 0;
    }

    /// Resume: a wait that timed out waits again. Whether a change was under way.
    pub(super) fn retry(&mut self) -> bool {
        self.timed_out = false;
        self.wait_steps = 0;
        self.running()
    }
}

impl RtCore {
    /// One 4 ms step of the changer: start at a held M6 of a job, or check the current
    /// step's inputs and go on (the next step's outputs, or the program resumed after the
    /// last). Runs after the interpolator's step, so `waiting` is the changer's while it runs.
    pub(super) fn tool_changer_step(&mut self) {
        if !self.changer.cfg.automatic() || self.job.active == 0 {
            return;
        }
        let Some(step) = self.changer.step else {
            if let Some(tool) = self.motion.interp.tool_change() {
                let c = &mut self.changer;
                c.on = (c.on & !c.cfg.number_mask()) | c.cfg.number_bits(tool);
                self.enter_step(0);
            }
            return;
        };
        let s = self.changer.cfg.steps()[usize::from(step)];
        let missing = s.wait & !self.io_logic.last;
        self.snap.io.waiting = IoBits(missing);
        // Timed out: held until Resume, as a program M function's wait.
        if self.changer.timed_out {
            return;
        }
        if missing == 0 {
            if usize::from(step) + 1 < usize::from(self.changer.cfg.len) {
                self.enter_step(step + 1);
            } else {
                // The change is complete: the program continues with no operator action.
                self.changer.end();
                self.motion.interp.resume();
            }
            return;
        }
        self.changer.wait_steps += 1;
        if self.changer.wait_steps > self.wait_limit_steps(missing) {
            self.changer.timed_out = true;
            self.snap.io.wait_timed_out = IoBits(missing);
        }
    }

    /// Step `k` begins: its outputs switch (pulses start as a program block's); its inputs
    /// are checked from the next 4 ms step on, so every step reaches the bus.
    fn enter_step(&mut self, k: u8) {
        let c = &mut self.changer;
        let s = c.cfg.steps()[usize::from(k)];
        c.on = (c.on | s.on) & !s.off;
        c.step = Some(k);
        c.wait_steps = 0;
        c.timed_out = false;
        self.start_pulses(s.pulse);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_tool_number_goes_on_its_outputs_bit_0_first_and_the_changer_owns_its_outputs() {
        let mut c = ToolChanger {
            len: 2,
            number_outputs: [5, 3, 0, 0, 0, 0, 0, 0],
            number_len: 2,
            ..ToolChanger::default()
        };
        c.steps[0] = MFunction {
            on: 0b1,
            ..MFunction::default()
        };
        c.steps[1] = MFunction {
            off: 0b10,
            wait: 0b100,
            ..MFunction::default()
        };
        // A step beyond `len` is not the changer's.
        c.steps[2].on = 1 << 40;
        assert_eq!(c.number_bits(1), 1 << 5);
        assert_eq!(c.number_bits(2), 1 << 3);
        assert_eq!(c.number_bits(3), 1 << 5 | 1 << 3);
        assert_eq!(c.owned(), 0b1 | 0b10 | 1 << 5 | 1 << 3);
        assert!(c.automatic() && !ToolChanger::default().automatic());
    }
}
