//! Digital inputs and outputs: the seam between the buses that carry them (CiA 401 I/O
//! modules and the drives' own 0x60FD/0x60FE on CANopen, the serial unit's I/O message, the
//! simulated machine) and the real-time core that gives them meaning (docs/io.md).
//!
//! The configuration numbers its inputs and outputs in the order it lists them; a bus is
//! built with an [`IoMap`] saying where each is wired, reads every input it serves into
//! [`crate::CycleFeedback::inputs`] in each cycle and writes [`crate::CycleCommand::outputs`]
//! in the same cycle, like the drives' process data. Bits are raw: what the wire reads (the
//! core applies each input's `invert`).

/// Most inputs, and most outputs, a machine has (one bit each of a `u64`).
pub const MAX_IO: usize = 64;

/// One bit per input (or output), bit k for the k-th of the configuration.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub struct IoBits(pub u64);

impl IoBits {
    pub const NONE: IoBits = IoBits(0);

    /// Bit `k` (false beyond [`MAX_IO`]).
    pub fn get(self, k: usize) -> bool {
        k < MAX_IO && self.0 & (1 << k) != 0
    }

    /// Sets bit `k` to `on` (ignored beyond [`MAX_IO`]).
    pub fn set(&mut self, k: usize, on: bool) {
        if k < MAX_IO {
            if on {
                self.0 |= 1 << k;
            } else {
                self.0 &= !(1 << k);
            }
        }
    }

    /// The mask of the first `n` bits.
    pub fn first(n: usize) -> IoBits {
        IoBits(if n >= MAX_IO {
            u64::MAX
        } else {
            (1u64 << n) - 1
        })
    }
}

/// Where one input or output is wired.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum IoPoint {
    /// A CiA 401 I/O module on the drives' CAN bus. `bit` counts from bit 0 of sub-index 1 of
    /// the module's 8-bit groups (inputs 0x6000, outputs 0x6200): bit 8 is sub-index 2 bit 0.
    Module { node: u8, bit: u8 },
    /// A drive's own digital inputs 0x60FD (bit 0 negative limit, 1 positive limit, 2 home
    /// switch, 3 interlock, 16..31 the manufacturer's) or outputs 0x60FE sub 1, bit 0..31.
    /// `axis` is the axis index ([`crate::SPINDLE_AXIS`] for the spindle drive).
    Drive { axis: u8, bit: u8 },
    /// The serial unit's I/O message, bit 0..63.
    Serial { bit: u8 },
    /// The built-in simulated machine (its inputs are switches it models or that
    /// `cncctl io sim-set` flips; its outputs are kept and read back).
    Sim,
}

impl IoPoint {
    /// The node of a CiA 401 module, if this point is on one.
    pub fn module_node(&self) -> Option<u8> {
        match *self {
            IoPoint::Module { node, .. } => Some(node),
            _ => None,
        }
    }
}

/// The wiring a bus serves: input k of [`crate::CycleFeedback::inputs`] is `inputs[k]`, output
/// k of [`crate::CycleCommand::outputs`] is `outputs[k]`. Points of another bus are not the
/// bus's to serve (their bits stay 0).
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct IoMap {
    pub inputs: Vec<IoPoint>,
    pub outputs: Vec<IoPoint>,
    /// Output k's value when the master cannot write it any more (bus broken, master dead):
    /// what a CiA 401 module is configured to fall to by itself (0x6206/0x6207).
    pub safe_outputs: IoBits,
}

impl IoMap {
    /// The CiA 401 modules the map uses, each once, in the order first named.
    pub fn modules(&self) -> Vec<u8> {
        let mut nodes: Vec<u8> = Vec::new();
        for n in self
            .inputs
            .iter()
            .chain(&self.outputs)
            .filter_map(IoPoint::module_node)
        {
            if !nodes.contains(&n) {
                nodes.push(n);
            }
        }
        nodes
    }

    /// Whether no point is wired.
    pub fn is_empty(&self) -> bool {
        self.inputs.is_empty() && self.outputs.is_empty()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bits_get_set_and_bounds() {
        let mut b = IoBits::NONE;
        b.set(3, true);
        b.set(63, true);
        b.set(64, true);
        assert!(b.get(3) && b.get(63) && !b.get(64) && !b.get(2));
        b.set(3, false);
        assert_eq!(b, IoBits(1 << 63));
        assert_eq!(IoBits::first(3), IoBits(0b111));
        assert_eq!(IoBits::first(64), IoBits(u64::MAX));
    }

    #[test]
    fn modules_listed_once_in_order() {
        let map = IoMap {
            inputs: vec![
                IoPoint::Module { node: 11, bit: 0 },
                IoPoint::Sim,
                IoPoint::Module { node: 10, bit: 3 },
            ],
            outputs: vec![IoPoint::Module { node: 11, bit: 1 }],
            safe_outputs: IoBits::NONE,
        };
        assert_eq!(map.modules(), vec![11, 10]);
    }
}
