//! The machine's outputs as a program switches them (docs/io.md): M functions that the
//! configuration binds to outputs (`[[io.outputs]] on/off`) or to inputs that confirm them
//! (`[[io.inputs]] confirms`). The interpreter keeps the outputs a program has switched on as
//! modal state; it rides with the block's technology state ([`crate::block::Spindle`]) through
//! compensation, the planner and the interpolator, so it takes effect where that state does:
//! before the motion of its block (LinuxCNC's order of execution), and at the stop before a
//! block without motion.

/// What a block asks of the outputs. Bit k is output k (inputs for `wait`) of the
/// configuration's lists.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct ProgramOutputs {
    /// Outputs the program has switched on (modal: M8 … M9).
    pub on: u64,
    /// Outputs the last pulsing block pulsed, and a count of such blocks: a pulse fires where
    /// the count changes, so two pulses in a row are two (both kept from block to block).
    pub pulse: u64,
    pub pulse_seq: u16,
    /// Inputs that must read 1 before this block's motion starts (not modal).
    pub wait: u64,
    /// The block has an M function bound to outputs or inputs (not modal): a technology
    /// block carries its state even when it changes nothing (M9 with coolant off in the
    /// program, on from an earlier MDI).
    pub touched: bool,
}

impl ProgramOutputs {
    /// The state at the start of a block: what stays in force from the one before.
    pub fn carried(self) -> ProgramOutputs {
        ProgramOutputs {
            on: self.on,
            pulse: self.pulse,
            pulse_seq: self.pulse_seq,
            ..ProgramOutputs::default()
        }
    }
}

/// One M function bound to outputs and inputs.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct MFunction {
    pub code: u16,
    /// Outputs it switches on, off, pulses; inputs it waits for.
    pub on: u64,
    pub off: u64,
    pub pulse: u64,
    pub wait: u64,
}

/// The machine's M functions on outputs (empty: none, every other M passes through).
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct MFunctions(Vec<MFunction>);

impl MFunctions {
    /// Adds `f` to the function of its code (one code may switch several outputs and wait
    /// for several inputs).
    pub fn add(&mut self, f: MFunction) {
        match self.0.iter_mut().find(|g| g.code == f.code) {
            Some(g) => {
                g.on |= f.on;
                g.off |= f.off;
                g.pulse |= f.pulse;
                g.wait |= f.wait;
            }
            None => self.0.push(f),
        }
    }

    pub fn get(&self, code: u16) -> Option<&MFunction> {
        self.0.iter().find(|f| f.code == code)
    }

    /// Applies M `code` to `st` (the block's state); false when the code is not bound.
    pub fn apply(&self, code: u16, st: &mut ProgramOutputs) -> bool {
        let Some(f) = self.get(code) else {
            return false;
        };
        st.on = (st.on | f.on) & !f.off;
        if f.pulse != 0 {
            st.pulse = f.pulse;
            st.pulse_seq = st.pulse_seq.wrapping_add(1);
        }
        st.wait |= f.wait;
        st.touched = true;
        true
    }

    pub fn is_empty(&self) -> bool {
        self.0.is_empty()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn on_off_pulse_wait_and_what_carries_over() {
        let mut t = MFunctions::default();
        t.add(MFunction {
            code: 8,
            on: 0b01,
            ..Default::default()
        });
        t.add(MFunction {
            code: 9,
            off: 0b11,
            ..Default::default()
        });
        t.add(MFunction {
            code: 10,
            on: 0b100,
            ..Default::default()
        });
        t.add(MFunction {
            code: 10,
            wait: 0b1,
            ..Default::default()
        });
        t.add(MFunction {
            code: 60,
            pulse: 0b1000,
            ..Default::default()
        });
        let mut st = ProgramOutputs::default();
        assert!(t.apply(8, &mut st) && st.on == 0b01 && st.touched);
        assert!(!t.apply(7, &mut st));
        assert!(t.apply(10, &mut st));
        assert_eq!((st.on, st.wait), (0b101, 0b1));
        let mut next = st.carried();
        assert_eq!((next.on, next.wait, next.touched), (0b101, 0, false));
        assert!(t.apply(60, &mut next) && next.pulse == 0b1000 && next.pulse_seq == 1);
        let mut last = next.carried();
        assert!(t.apply(9, &mut last));
        assert_eq!((last.on, last.pulse, last.pulse_seq), (0b100, 0b1000, 1));
    }
}
