//! The simulated machine's inputs and outputs (docs/io.md): switches it models on the axes
//! (limit and home switches), inputs at rest (the e-stop chain and the door closed), and a
//! shared handle that flips an input from outside (`cncctl io sim-set`).

use std::sync::Arc;
use std::sync::atomic::{AtomicU8, Ordering};

use hal::io::{IoBits, MAX_IO};

use crate::probe::SimProbe;

/// One simulated input: its wire value at rest, and the switch it models on an axis (reached
/// at and beyond `at_mm` of `axis`, on the side `side`: -1 at and below, +1 at and above).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SimInput {
    pub rest: bool,
    pub switch: Option<(usize, f64, f64)>,
    /// The probe: reads 1 while it touches the simulated workpiece or tool setter
    /// ([`crate::probe`]).
    pub probe: bool,
}

/// Inputs set from outside: per input, unset (the model's value), or 0 / 1.
#[derive(Clone, Debug)]
pub struct SimInputs(Arc<[AtomicU8; MAX_IO]>);

const UNSET: u8 = 2;

impl Default for SimInputs {
    fn default() -> Self {
        SimInputs(Arc::new(std::array::from_fn(|_| AtomicU8::new(UNSET))))
    }
}

impl SimInputs {
    /// Input `k` reads `value` from now on (`None`: the model's value again).
    pub fn set(&self, k: usize, value: Option<bool>) {
        if let Some(slot) = self.0.get(k) {
            slot.store(value.map_or(UNSET, u8::from), Ordering::Relaxed);
        }
    }

    fn get(&self, k: usize) -> Option<bool> {
        match self.0[k].load(Ordering::Relaxed) {
            UNSET => None,
            v => Some(v == 1),
        }
    }
}

/// The simulated I/O of a [`crate::bus::SimBus`].
#[derive(Clone, Debug, Default)]
pub struct SimIo {
    pub inputs: Vec<SimInput>,
    pub set: SimInputs,
    /// The outputs as last written.
    pub outputs: IoBits,
    /// What the probe inputs touch.
    pub probe: Option<SimProbe>,
}

/// Where the default machine's limit switches sit on an axis without soft limits, mm (the
/// daemon's `[io]` default puts them 5 mm beyond the soft limits where there are some).
pub const DEFAULT_LIMIT_MM: f64 = 2000.0;

impl SimIo {
    /// The simulated machine's own inputs for `axes` axes, in the daemon's default order
    /// (docs/io.md): `estop` (closed), `x_limit_neg`, `x_limit_pos`, … for the first three
    /// axes, `door` (closed).
    pub fn machine_default(axes: usize) -> Vec<SimInput> {
        let closed = SimInput {
            rest: true,
            switch: None,
            probe: false,
        };
        let mut inputs = vec![closed];
        for a in 0..axes.min(3) {
            for side in [-1.0, 1.0] {
                inputs.push(SimInput {
                    rest: false,
                    switch: Some((a, side * DEFAULT_LIMIT_MM, side)),
                    probe: false,
                });
            }
        }
        inputs.push(closed);
        inputs
    }

    /// The wire values of the inputs, with the axes at `positions_mm` (as the drives report
    /// them: machine coordinates).
    pub fn read(&self, positions_mm: &[f64]) -> IoBits {
        let mut bits = IoBits::NONE;
        for (k, inp) in self.inputs.iter().enumerate().take(MAX_IO) {
            let modelled = match inp.switch {
                _ if inp.probe => {
                    let touches = self.probe.as_ref().is_some_and(|p| p.touches(positions_mm));
                    touches != inp.rest
                }
                Some((axis, at, side)) => {
                    let reached = positions_mm
                        .get(axis)
                        .is_some_and(|&p| (p - at) * side >= 0.0);
                    reached != inp.rest
                }
                None => inp.rest,
            };
            bits.set(k, self.set.get(k).unwrap_or(modelled));
        }
        bits
    }
}
