//! The drive unit's digital I/O (protocol version 4): which bits of the unit's 64-bit input
//! and output words are the configuration's inputs and outputs ([`IoPoint::Serial`]), the
//! safe output word the unit falls to on link loss, and the newest input word.
//!
//! The safe output word goes out in every request until a reply to a request that carried it
//! says the unit holds it; a reply saying the unit holds none (it restarted) sends it again.

use super::message::{IoCommand, IoStatus};
use crate::io::{IoBits, IoMap, IoPoint, MAX_IO};

/// Point `k` of the configuration is wired to bit `bit` of the unit's word.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
struct Wire {
    k: usize,
    bit: u8,
}

/// The points of `points` this unit serves (Serial points within the word).
fn wires(points: &[IoPoint]) -> Vec<Wire> {
    points
        .iter()
        .enumerate()
        .take(MAX_IO)
        .filter_map(|(k, p)| match *p {
            IoPoint::Serial { bit } if usize::from(bit) < MAX_IO => Some(Wire { k, bit }),
            _ => None,
        })
        .collect()
}

/// The first Serial point of `map` whose bit is beyond the unit's 64-bit words.
pub fn bad_bit(map: &IoMap) -> Option<u8> {
    map.inputs
        .iter()
        .chain(&map.outputs)
        .find_map(|p| match *p {
            IoPoint::Serial { bit } if usize::from(bit) >= MAX_IO => Some(bit),
            _ => None,
        })
}

#[derive(Clone, Debug, Default)]
pub struct UnitIo {
    inputs: Vec<Wire>,
    outputs: Vec<Wire>,
    /// `IoMap::safe_outputs` in the unit's bits.
    safe_word: u64,
    /// A reply to a request that carried the safe word said the unit holds it.
    safe_confirmed: bool,
    /// The last request carried the safe word.
    safe_sent: bool,
    /// The input word of the newest reply (0 before the first).
    input_word: u64,
}

impl UnitIo {
    pub fn new(map: &IoMap) -> UnitIo {
        let outputs = wires(&map.outputs);
        let safe_word = word_of(&outputs, map.safe_outputs);
        UnitIo {
            inputs: wires(&map.inputs),
            outputs,
            safe_word,
            ..UnitIo::default()
        }
    }

    /// Whether any point is wired to the unit: the link then speaks version 4.
    pub fn is_used(&self) -> bool {
        !(self.inputs.is_empty() && self.outputs.is_empty())
    }

    /// The I/O record of this tick's request: `outputs` in the unit's bits, and the safe word
    /// until the unit confirmed it.
    pub fn command(&mut self, outputs: IoBits) -> IoCommand {
        self.safe_sent = !self.safe_confirmed;
        IoCommand {
            outputs: word_of(&self.outputs, outputs),
            safe_outputs: self.safe_sent.then_some(self.safe_word),
        }
    }

    /// The I/O record of the reply to the last request.
    pub fn on_status(&mut self, s: IoStatus) {
        self.input_word = s.inputs;
        self.safe_confirmed = s.safe_held && (self.safe_confirmed || self.safe_sent);
    }

    /// The inputs of the newest reply, bit k for input k.
    pub fn inputs(&self) -> IoBits {
        let mut bits = IoBits::NONE;
        for w in &self.inputs {
            bits.set(w.k, self.input_word & (1 << w.bit) != 0);
        }
        bits
    }

    /// The unit may have been swapped: send the safe word again.
    pub fn forget_unit(&mut self) {
        self.safe_confirmed = false;
    }
}

/// Output bits `bits` (bit k for output k) in the unit's word.
fn word_of(outputs: &[Wire], bits: IoBits) -> u64 {
    outputs
        .iter()
        .filter(|w| bits.get(w.k))
        .fold(0, |word, w| word | 1 << w.bit)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn map() -> IoMap {
        IoMap {
            inputs: vec![
                IoPoint::Serial { bit: 5 },
                IoPoint::Sim,
                IoPoint::Serial { bit: 63 },
            ],
            outputs: vec![
                IoPoint::Module { node: 3, bit: 0 },
                IoPoint::Serial { bit: 0 },
                IoPoint::Serial { bit: 40 },
            ],
            safe_outputs: IoBits(0b101),
        }
    }

    #[test]
    fn bits_map_both_ways_and_the_safe_word_is_sent_until_confirmed() {
        let mut io = UnitIo::new(&map());
        assert!(io.is_used());
        assert!(!UnitIo::new(&IoMap::default()).is_used());
        let c = io.command(IoBits(0b110));
        assert_eq!((c.outputs, c.safe_outputs), (1 | 1 << 40, Some(1 << 40)));
        io.on_status(IoStatus {
            inputs: 1 << 5 | 1 << 63 | 1 << 7,
            safe_held: true,
        });
        assert_eq!(io.inputs(), IoBits(0b101));
        assert_eq!(io.command(IoBits::NONE).safe_outputs, None);
        // The unit restarted: it holds no safe word; ours goes out again.
        io.on_status(IoStatus::default());
        assert_eq!(io.command(IoBits::NONE).safe_outputs, Some(1 << 40));
    }

    #[test]
    fn a_bit_beyond_the_word_is_found() {
        let mut m = map();
        assert_eq!(bad_bit(&m), None);
        m.outputs.push(IoPoint::Serial { bit: 64 });
        assert_eq!(bad_bit(&m), Some(64));
    }
}
