//! The communication and mapping objects of one PDO in a simulated node (0x14xx/0x16xx for
//! an RPDO, 0x18xx/0x1Axx for a TPDO), strict in the CiA 301 order as real devices are: a
//! valid PDO's COB-ID changes only through invalid (bit 31 set first), the mapping count only
//! while the PDO is invalid, mapping entries only with the PDO invalid and its count 0.

use hal::canopen::sdo::abort;

/// Bit 31 of a PDO COB-ID: the PDO is not valid.
pub const INVALID: u32 = 0x8000_0000;

/// One PDO's objects.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct PdoObjects {
    /// Sub 1 of the communication object.
    pub cob_id: u32,
    /// Sub 2: transmission type (1..240 synchronous, 254/255 event-driven).
    pub kind: u8,
    /// Mapping entries (sub 1..8 of the mapping object).
    pub map: [u32; 8],
    /// Sub 0 of the mapping object: the entries in use.
    pub count: u8,
}

impl PdoObjects {
    /// Power-on values: invalid and unmapped, so an unconfigured node sends nothing.
    pub fn unmapped(cob_id: u16) -> PdoObjects {
        PdoObjects {
            cob_id: INVALID | u32::from(cob_id),
            kind: 255,
            map: [0; 8],
            count: 0,
        }
    }

    /// Valid on its predefined COB-ID with `count` entries mapped.
    pub fn active(&self, cob_id: u16, count: u8) -> bool {
        self.cob_id == u32::from(cob_id) && self.count == count && count > 0
    }

    /// Synchronous (applied or sent at SYNC) rather than event-driven.
    pub fn is_sync(&self) -> bool {
        (1..=240).contains(&self.kind)
    }

    /// The entries in use.
    pub fn entries(&self) -> &[u32] {
        &self.map[..usize::from(self.count.min(8))]
    }

    /// Writes sub `sub` of the communication object.
    pub fn write_comm(&mut self, sub: u8, v: u32) -> Result<(), u32> {
        match sub {
            1 if self.cob_id & INVALID == 0 && v & INVALID == 0 && v != self.cob_id => {
                Err(abort::VALUE_RANGE)
            }
            1 => {
                self.cob_id = v;
                Ok(())
            }
            2 if v <= 255 => {
                self.kind = v as u8;
                Ok(())
            }
            2 => Err(abort::VALUE_RANGE),
            _ => Err(abort::NO_SUBINDEX),
        }
    }

    /// Writes sub `sub` of the mapping object; `mappable` says which entries the node has.
    pub fn write_map(
        &mut self,
        sub: u8,
        v: u32,
        mappable: impl Fn(u32) -> bool,
    ) -> Result<(), u32> {
        if self.cob_id & INVALID == 0 {
            return Err(abort::DEVICE_STATE);
        }
        match sub {
            0 if v as usize <= self.map.len() => {
                if self.map[..v as usize].iter().any(|&e| !mappable(e)) {
                    return Err(abort::CANNOT_MAP);
                }
                self.count = v as u8;
                Ok(())
            }
            0 => Err(abort::VALUE_RANGE),
            1..=8 if self.count != 0 => Err(abort::DEVICE_STATE),
            1..=8 if !mappable(v) => Err(abort::CANNOT_MAP),
            1..=8 => {
                self.map[usize::from(sub - 1)] = v;
                Ok(())
            }
            _ => Err(abort::NO_SUBINDEX),
        }
    }

    /// Reads sub `sub` of the communication (`comm`) or mapping object.
    pub fn read(&self, comm: bool, sub: u8) -> Result<(u32, u8), u32> {
        match (comm, sub) {
            (true, 1) => Ok((self.cob_id, 4)),
            (true, 2) => Ok((u32::from(self.kind), 1)),
            (false, 0) => Ok((u32::from(self.count), 1)),
            (false, 1..=8) => Ok((self.map[usize::from(sub - 1)], 4)),
            _ => Err(abort::NO_SUBINDEX),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn remapping_only_in_the_cia_301_order() {
        let mut p = PdoObjects::unmapped(0x28A);
        let any = |_| true;
        p.write_map(1, 0x60FD_0020, any).unwrap();
        p.write_map(0, 1, any).unwrap();
        assert_eq!(p.write_map(1, 0, any), Err(abort::DEVICE_STATE));
        p.write_comm(1, 0x28A).unwrap();
        assert!(p.active(0x28A, 1));
        assert_eq!(p.write_comm(1, 0x29A), Err(abort::VALUE_RANGE));
        assert_eq!(p.write_map(0, 0, any), Err(abort::DEVICE_STATE));
        assert_eq!(
            PdoObjects::unmapped(1).write_map(1, 5, |_| false),
            Err(abort::CANNOT_MAP)
        );
    }
}
