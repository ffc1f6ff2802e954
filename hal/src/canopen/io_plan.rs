//! Where each input and output of the bus's [`crate::io::IoMap`] travels: a bit of a CiA 401
//! module's groups, or a bit of a drive's 0x60FD / 0x60FE:1. Resolved once when the master is
//! built, so the tick only walks two short lists. A child of `master`.

use super::*;
use crate::io::{IoBits, IoPoint};

/// The carrier of one input or output.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum Carrier {
    /// Bit `bit` of the module at index `module` of the master's modules.
    Module { module: usize, bit: u8 },
    /// Bit `bit` of the drive at index `node` of the master's nodes.
    Drive { node: usize, bit: u8 },
}

/// Which of a drive's own I/O objects the map uses (only those are mapped into PDOs, so a
/// drive without points keeps the plain PDO1 layout).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub(super) struct DriveIo {
    pub(super) inputs: bool,
    pub(super) outputs: bool,
}

/// Input k / output k of the map and its carrier, for the points this bus serves.
pub(super) struct IoPlan {
    pub(super) inputs: Vec<(usize, Carrier)>,
    pub(super) outputs: Vec<(usize, Carrier)>,
}

impl IoPlan {
    /// The plan of `cfg.io`; `modules` are the module node ids in the master's order.
    pub(super) fn new(cfg: &CanOpenConfig, modules: &[u8]) -> Result<IoPlan, CanOpenError> {
        let resolve = |points: &[IoPoint]| -> Result<Vec<(usize, Carrier)>, CanOpenError> {
            let mut v = Vec::new();
            for (k, p) in points.iter().enumerate().take(crate::io::MAX_IO) {
                if let Some(c) = carrier(cfg, modules, p)? {
                    v.push((k, c));
                }
            }
            Ok(v)
        };
        Ok(IoPlan {
            inputs: resolve(&cfg.io.inputs)?,
            outputs: resolve(&cfg.io.outputs)?,
        })
    }

    /// The drive I/O objects node `node` carries.
    pub(super) fn drive_io(&self, node: usize) -> DriveIo {
        let on = |v: &[(usize, Carrier)]| {
            v.iter()
                .any(|(_, c)| matches!(*c, Carrier::Drive { node: n, .. } if n == node))
        };
        DriveIo {
            inputs: on(&self.inputs),
            outputs: on(&self.outputs),
        }
    }

    /// Groups of module `module`'s inputs and outputs the map needs (its highest bits).
    pub(super) fn module_groups(&self, module: usize) -> (u8, u8) {
        let groups = |v: &[(usize, Carrier)]| {
            v.iter()
                .filter_map(|(_, c)| match *c {
                    Carrier::Module { module: m, bit } if m == module => {
                        Some(cia401::groups_for(bit))
                    }
                    _ => None,
                })
                .max()
                .unwrap_or(0)
        };
        (groups(&self.inputs), groups(&self.outputs))
    }

    /// The module bits of `outputs` that travel on module `module`.
    pub(super) fn module_bits(&self, module: usize, outputs: IoBits) -> u64 {
        let mut bits = 0u64;
        for &(k, c) in &self.outputs {
            if let Carrier::Module { module: m, bit } = c
                && m == module
                && outputs.get(k)
            {
                bits |= 1 << bit;
            }
        }
        bits
    }

    /// The 0x60FE:1 bits of `outputs` that travel on drive `node`.
    pub(super) fn drive_bits(&self, node: usize, outputs: IoBits) -> u32 {
        let mut bits = 0u32;
        for &(k, c) in &self.outputs {
            if let Carrier::Drive { node: n, bit } = c
                && n == node
                && outputs.get(k)
            {
                bits |= 1 << bit;
            }
        }
        bits
    }

    /// Input k from what module or drive last sent: `module_bits(m)` / `drive_bits(n)`.
    pub(super) fn inputs_from(
        &self,
        module_bits: impl Fn(usize) -> u64,
        drive_bits: impl Fn(usize) -> u32,
    ) -> IoBits {
        let mut bits = IoBits::NONE;
        for &(k, c) in &self.inputs {
            let on = match c {
                Carrier::Module { module, bit } => module_bits(module) & (1 << bit) != 0,
                Carrier::Drive { node, bit } => drive_bits(node) & (1 << bit) != 0,
            };
            bits.set(k, on);
        }
        bits
    }
}

/// The carrier of point `p` on this bus; `None` for another bus's point.
fn carrier(
    cfg: &CanOpenConfig,
    modules: &[u8],
    p: &IoPoint,
) -> Result<Option<Carrier>, CanOpenError> {
    Ok(Some(match *p {
        IoPoint::Module { node, bit } => {
            if bit >= 8 * cia401::MAX_GROUPS {
                return Err(CanOpenError::ModuleBitRange { node, bit });
            }
            let module = modules.iter().position(|&n| n == node).unwrap_or(0);
            Carrier::Module { module, bit }
        }
        IoPoint::Drive { axis, bit } => {
            let node = match usize::from(axis) {
                a if a < cfg.nodes.len() => a,
                _ if axis == crate::SPINDLE_AXIS && cfg.spindle.is_some() => cfg.nodes.len(),
                _ => return Err(CanOpenError::IoDriveMissing { axis }),
            };
            if bit >= 32 {
                return Err(CanOpenError::IoDriveBitRange { axis, bit });
            }
            Carrier::Drive { node, bit }
        }
        IoPoint::Serial { .. } | IoPoint::Sim => return Ok(None),
    }))
}

/// Checks the module node ids: each a node id, none the master's or a drive's.
pub(super) fn check_modules(cfg: &CanOpenConfig) -> Result<(), CanOpenError> {
    for node in cfg.io.modules() {
        let id = NodeId::new(node)?;
        let drive = cfg.nodes.iter().any(|n| n.node_id == id)
            || cfg.spindle.as_ref().is_some_and(|s| s.node_id == id);
        if id == cfg.master_node_id || drive {
            return Err(CanOpenError::ModuleNodeUsed { node });
        }
    }
    Ok(())
}
