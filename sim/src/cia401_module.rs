//! A simulated CANopen CiA 401 generic I/O module: 8-bit groups of digital inputs (0x6000)
//! and outputs (0x6200), their error mode (0x6206) and error values (0x6207); NMT slave,
//! expedited SDO server, TPDO1 with input groups (synchronous, or event-driven on change),
//! RPDO1 with output groups (applied on arrival when event-driven, at SYNC when synchronous),
//! heartbeat producer (0x1017) and consumer (0x1016). Its terminals are a shared
//! [`ModuleIo`]: a test or the `sim-can` control channel sets the inputs and reads the outputs.
//!
//! When the master's heartbeat stays away for the consumer time, the module falls to its
//! error state by itself, as a real one does: every output whose bit is set in 0x6206 takes
//! its value from 0x6207, EMCY 8130h, NMT pre-operational (CiA 301 0x1029 default), and no
//! RPDO is taken until the master starts it again. No I/O: the caller feeds frames and time.

use std::sync::Arc;
use std::sync::atomic::{AtomicU64, Ordering};

use hal::canopen::cia401::{self, ERROR_MODE, ERROR_VALUE, INPUTS, OUTPUTS};
use hal::canopen::emcy::Emcy;
use hal::canopen::sdo::{self, Request, abort};
use hal::canopen::{Frame, cob, nmt};

use crate::can_node::Injection;
use crate::cia402_drive::COMMUNICATION_LOST;
use crate::pdo_objects::PdoObjects;

/// EMCY code of an RPDO of the wrong length (CiA 301: "PDO not processed due to length error").
pub const PDO_LENGTH_ERROR: u16 = 0x8210;

/// The module's terminals, shared: inputs set from outside, outputs read (bit b is group
/// b / 8 + 1, bit b % 8).
#[derive(Clone, Debug, Default)]
pub struct ModuleIo {
    inputs: Arc<AtomicU64>,
    outputs: Arc<AtomicU64>,
}

impl ModuleIo {
    pub fn set_input(&self, bit: u8, on: bool) {
        let mask = 1u64.checked_shl(u32::from(bit)).unwrap_or(0);
        if on {
            self.inputs.fetch_or(mask, Ordering::Relaxed);
        } else {
            self.inputs.fetch_and(!mask, Ordering::Relaxed);
        }
    }

    pub fn set_inputs(&self, bits: u64) {
        self.inputs.store(bits, Ordering::Relaxed);
    }

    pub fn inputs(&self) -> u64 {
        self.inputs.load(Ordering::Relaxed)
    }

    pub fn outputs(&self) -> u64 {
        self.outputs.load(Ordering::Relaxed)
    }

    fn set_outputs(&self, bits: u64) {
        self.outputs.store(bits, Ordering::Relaxed);
    }
}

/// Its object dictionary beyond the terminals.
#[derive(Clone, Copy, Debug)]
struct Objects {
    tpdo: PdoObjects,
    rpdo: PdoObjects,
    heartbeat_ms: u16,
    consumer: u32,
    /// 0x6206 sub 1..8.
    error_mode: [u8; 8],
    /// 0x6207 sub 1..8.
    error_value: [u8; 8],
}

impl Objects {
    fn defaults(id: u8) -> Objects {
        Objects {
            tpdo: PdoObjects::unmapped(cob::TPDO1 + u16::from(id)),
            rpdo: PdoObjects::unmapped(cob::RPDO1 + u16::from(id)),
            heartbeat_ms: 0,
            consumer: 0,
            error_mode: [0; 8],
            error_value: [0; 8],
        }
    }
}

pub struct Cia401Module {
    pub id: u8,
    /// Groups of inputs and of outputs it has (1..=8).
    pub groups: u8,
    pub io: ModuleIo,
    pub inject: Injection,
    nmt: u8,
    od: Objects,
    /// Outputs of a synchronous RPDO, applied at the next SYNC.
    latched: Option<u64>,
    /// Inputs last sent by an event-driven TPDO.
    last_sent: Option<u64>,
    next_heartbeat_ms: u64,
    master_heartbeat_ms: Option<u64>,
    booted: bool,
}

impl Cia401Module {
    /// Module `id` with `groups` groups of 8 inputs and of 8 outputs (clamped to 1..=8).
    pub fn new(id: u8, groups: u8) -> Cia401Module {
        Cia401Module {
            id,
            groups: groups.clamp(1, cia401::MAX_GROUPS),
            io: ModuleIo::default(),
            inject: Injection::default(),
            nmt: nmt::state::PRE_OPERATIONAL,
            od: Objects::defaults(id),
            latched: None,
            last_sent: None,
            next_heartbeat_ms: 0,
            master_heartbeat_ms: None,
            booted: false,
        }
    }

    pub fn nmt_state(&self) -> u8 {
        self.nmt
    }

    /// The heartbeat consumer entry 0x1016:1.
    pub fn consumer(&self) -> u32 {
        self.od.consumer
    }

    /// 0x6206 and 0x6207 of group `group` (from 1).
    pub fn error_setting(&self, group: u8) -> (u8, u8) {
        let g = usize::from(group.clamp(1, 8) - 1);
        (self.od.error_mode[g], self.od.error_value[g])
    }

    /// One line for a test: NMT state, inputs, outputs, consumer entry.
    pub fn state_line(&self) -> String {
        format!(
            "state module {} nmt {:02X} inputs {:016X} outputs {:016X} consumer {:08X}",
            self.id,
            self.nmt,
            self.io.inputs(),
            self.io.outputs(),
            self.od.consumer
        )
    }

    /// NMT reset: reset node also returns the outputs and the application objects (error
    /// mode and values) to their power-on values; reset communication only 0x1000..0x1FFF.
    fn boot(&mut self, application: bool, now_ms: u64, out: &mut Vec<Frame>) {
        let (mode, value) = (self.od.error_mode, self.od.error_value);
        self.od = Objects::defaults(self.id);
        if application {
            self.io.set_outputs(0);
        } else {
            (self.od.error_mode, self.od.error_value) = (mode, value);
        }
        self.nmt = nmt::state::PRE_OPERATIONAL;
        self.latched = None;
        self.last_sent = None;
        self.master_heartbeat_ms = None;
        self.next_heartbeat_ms = now_ms;
        out.push(nmt::heartbeat(self.id, nmt::state::BOOT_UP));
    }

    /// Handles one received frame.
    pub fn handle(&mut self, f: &Frame, now_ms: u64, out: &mut Vec<Frame>) {
        if self.inject.silent {
            return;
        }
        let p = f.payload();
        if f.id == cob::NMT {
            if p.len() == 2 && (p[1] == 0 || p[1] == self.id) {
                self.on_nmt(p[0], now_ms, out);
            }
            return;
        }
        if f.id == cob::SYNC {
            return self.on_sync(out);
        }
        let (code, node) = cob::split(f.id);
        let consumer_id = ((self.od.consumer >> 16) & 0x7F) as u8;
        match code {
            cob::HEARTBEAT if node == consumer_id && consumer_id != 0 => {
                self.master_heartbeat_ms = Some(now_ms);
            }
            cob::RPDO1 if node == self.id && self.nmt == nmt::state::OPERATIONAL => {
                self.on_rpdo(p, out);
            }
            cob::SDO_RX if node == self.id && self.nmt != nmt::state::STOPPED => {
                out.push(self.answer_sdo(p));
            }
            _ => {}
        }
    }

    fn on_nmt(&mut self, cmd: u8, now_ms: u64, out: &mut Vec<Frame>) {
        match nmt::Command::from_byte(cmd) {
            Some(nmt::Command::Start) => self.nmt = nmt::state::OPERATIONAL,
            Some(nmt::Command::Stop) => self.nmt = nmt::state::STOPPED,
            Some(nmt::Command::EnterPreOperational) => self.nmt = nmt::state::PRE_OPERATIONAL,
            Some(nmt::Command::ResetNode) => self.boot(true, now_ms, out),
            Some(nmt::Command::ResetCommunication) => self.boot(false, now_ms, out),
            None => {}
        }
    }

    fn rpdo_active(&self) -> bool {
        let count = self.od.rpdo.count;
        self.od.rpdo.active(cob::RPDO1 + u16::from(self.id), count)
    }

    fn on_rpdo(&mut self, p: &[u8], out: &mut Vec<Frame>) {
        if !self.rpdo_active() {
            return;
        }
        if p.len() != usize::from(self.od.rpdo.count) {
            let e = Emcy {
                code: PDO_LENGTH_ERROR,
                register: 0x11,
                vendor: [0; 5],
            };
            out.push(e.encode(self.id));
            return;
        }
        let bits = cia401::decode_groups(p);
        if self.od.rpdo.is_sync() {
            self.latched = Some(bits);
        } else {
            self.apply(bits);
        }
    }

    /// Byte k of an RPDO goes to the output group its mapping entry k names.
    fn apply(&mut self, pdo_bits: u64) {
        let mut outputs = self.io.outputs();
        for (k, &entry) in self.od.rpdo.entries().iter().enumerate() {
            if let Some(g) = cia401::entry_group(OUTPUTS, entry) {
                let shift = 8 * u32::from(g - 1);
                let byte = u64::from(cia401::group_of(pdo_bits, k as u8 + 1));
                outputs = (outputs & !(0xFF << shift)) | (byte << shift);
            }
        }
        self.io.set_outputs(outputs);
    }

    /// The TPDO: byte k is the input group its mapping entry k names.
    fn tpdo(&self) -> Frame {
        let inputs = self.io.inputs();
        let mut bits = 0u64;
        for (k, &entry) in self.od.tpdo.entries().iter().enumerate() {
            if let Some(g) = cia401::entry_group(INPUTS, entry) {
                bits |= u64::from(cia401::group_of(inputs, g)) << (8 * k);
            }
        }
        let count = self.od.tpdo.count;
        let len = if self.inject.corrupt_pdo {
            count.saturating_sub(1)
        } else {
            count
        };
        cia401::encode_groups(cob::TPDO1 + u16::from(self.id), bits, len)
    }

    fn tpdo_active(&self) -> bool {
        let count = self.od.tpdo.count;
        self.od.tpdo.active(cob::TPDO1 + u16::from(self.id), count)
    }

    fn on_sync(&mut self, out: &mut Vec<Frame>) {
        if self.nmt != nmt::state::OPERATIONAL {
            return;
        }
        if let Some(bits) = self.latched.take() {
            self.apply(bits);
        }
        if self.tpdo_active() && self.od.tpdo.is_sync() {
            out.push(self.tpdo());
        }
    }

    /// Time passes: boot at power-on, the heartbeat, event-driven inputs, the consumer watch.
    pub fn poll(&mut self, now_ms: u64, out: &mut Vec<Frame>) {
        if self.inject.silent {
            return; // a silent module from the start is one that is not powered yet
        }
        if !self.booted {
            self.booted = true;
            self.boot(true, now_ms, out);
        }
        let hb = u64::from(self.od.heartbeat_ms);
        if hb > 0 && now_ms >= self.next_heartbeat_ms {
            self.next_heartbeat_ms = now_ms + hb;
            if !self.inject.drop_heartbeat {
                out.push(nmt::heartbeat(self.id, self.nmt));
            }
        }
        let event_driven = self.tpdo_active() && !self.od.tpdo.is_sync();
        if event_driven && self.nmt == nmt::state::OPERATIONAL {
            let inputs = self.io.inputs();
            if self.last_sent != Some(inputs) {
                self.last_sent = Some(inputs);
                out.push(self.tpdo());
            }
        }
        self.watch_master(now_ms, out);
    }

    /// The heartbeat consumer: from the first master heartbeat on, its absence for the
    /// consumer time puts the outputs of 0x6206 to their 0x6207 values.
    fn watch_master(&mut self, now_ms: u64, out: &mut Vec<Frame>) {
        let consumer_ms = u64::from(self.od.consumer & 0xFFFF);
        let Some(last) = self.master_heartbeat_ms else {
            return;
        };
        if consumer_ms == 0 || now_ms.saturating_sub(last) <= consumer_ms {
            return;
        }
        self.master_heartbeat_ms = None;
        self.enter_error_state();
        let e = Emcy {
            code: COMMUNICATION_LOST,
            register: 0x11,
            vendor: [0; 5],
        };
        out.push(e.encode(self.id));
        if self.nmt == nmt::state::OPERATIONAL {
            self.nmt = nmt::state::PRE_OPERATIONAL;
        }
    }

    /// Every output whose bit is set in 0x6206 takes its value from 0x6207.
    pub fn enter_error_state(&mut self) {
        let mut outputs = self.io.outputs();
        for g in 0..usize::from(self.groups) {
            let shift = 8 * g;
            let mode = u64::from(self.od.error_mode[g]) << shift;
            let value = u64::from(self.od.error_value[g]) << shift;
            outputs = (outputs & !mode) | (value & mode);
        }
        self.latched = None;
        self.io.set_outputs(outputs);
    }

    fn answer_sdo(&mut self, p: &[u8]) -> Frame {
        let id = self.id;
        match sdo::parse_request(p) {
            Ok(Request::Download {
                index,
                subindex,
                value,
                ..
            }) => match self.write(index, subindex, value) {
                Ok(()) => sdo::download_ok(id, index, subindex),
                Err(code) => sdo::abort(id, index, subindex, code),
            },
            Ok(Request::Upload { index, subindex }) => match self.read(index, subindex) {
                Ok((value, size)) => sdo::upload_ok(id, index, subindex, value, size),
                Err(code) => sdo::abort(id, index, subindex, code),
            },
            Err(code) => sdo::abort(id, 0, 0, code),
        }
    }

    /// Sub `sub` as a group index 0..groups, if it names one of its groups.
    fn group(&self, sub: u8) -> Result<usize, u32> {
        if (1..=self.groups).contains(&sub) {
            Ok(usize::from(sub - 1))
        } else {
            Err(abort::NO_SUBINDEX)
        }
    }

    fn write(&mut self, index: u16, sub: u8, v: u32) -> Result<(), u32> {
        let groups = self.groups;
        let mappable =
            move |idx: u16| move |e: u32| cia401::entry_group(idx, e).is_some_and(|g| g <= groups);
        let byte = u8::try_from(v).map_err(|_| abort::VALUE_RANGE);
        match (index, sub) {
            (0x1800, _) => self.od.tpdo.write_comm(sub, v),
            (0x1400, _) => self.od.rpdo.write_comm(sub, v),
            (0x1A00, _) => self.od.tpdo.write_map(sub, v, mappable(INPUTS)),
            (0x1600, _) => self.od.rpdo.write_map(sub, v, mappable(OUTPUTS)),
            (0x1017, 0) => {
                self.od.heartbeat_ms = u16::try_from(v).map_err(|_| abort::VALUE_RANGE)?;
                Ok(())
            }
            (0x1016, 1) => {
                self.od.consumer = v;
                Ok(())
            }
            (ERROR_MODE, _) => {
                self.od.error_mode[self.group(sub)?] = byte?;
                Ok(())
            }
            (ERROR_VALUE, _) => {
                self.od.error_value[self.group(sub)?] = byte?;
                Ok(())
            }
            (OUTPUTS, _) => {
                let shift = 8 * self.group(sub)?;
                let outputs = self.io.outputs() & !(0xFF << shift);
                self.io.set_outputs(outputs | (u64::from(byte?) << shift));
                Ok(())
            }
            (0x1000 | INPUTS, _) => Err(abort::READ_ONLY),
            (0x1016 | 0x1017, _) => Err(abort::NO_SUBINDEX),
            _ => Err(abort::NO_OBJECT),
        }
    }

    fn read(&self, index: u16, sub: u8) -> Result<(u32, u8), u32> {
        let groups = u32::from(self.groups);
        let byte = |bits: u64| -> Result<(u32, u8), u32> {
            let g = self.group(sub)? as u8 + 1;
            Ok((u32::from(cia401::group_of(bits, g)), 1))
        };
        match (index, sub) {
            // CiA 401 device with digital inputs and outputs.
            (0x1000, 0) => Ok((0x0003_0191, 4)),
            (0x1800, _) => self.od.tpdo.read(true, sub),
            (0x1400, _) => self.od.rpdo.read(true, sub),
            (0x1A00, _) => self.od.tpdo.read(false, sub),
            (0x1600, _) => self.od.rpdo.read(false, sub),
            (0x1017, 0) => Ok((u32::from(self.od.heartbeat_ms), 2)),
            (0x1016, 1) => Ok((self.od.consumer, 4)),
            (INPUTS | OUTPUTS | ERROR_MODE | ERROR_VALUE, 0) => Ok((groups, 1)),
            (INPUTS, _) => byte(self.io.inputs()),
            (OUTPUTS, _) => byte(self.io.outputs()),
            (ERROR_MODE, _) => Ok((u32::from(self.od.error_mode[self.group(sub)?]), 1)),
            (ERROR_VALUE, _) => Ok((u32::from(self.od.error_value[self.group(sub)?]), 1)),
            _ => Err(abort::NO_OBJECT),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sdo_write(m: &mut Cia401Module, index: u16, sub: u8, v: u32) -> Result<(), u32> {
        let mut out = Vec::new();
        m.handle(&sdo::download(m.id, index, sub, v, 4), 0, &mut out);
        match sdo::parse_response(out[0].payload()) {
            Some(sdo::Response::Abort { code, .. }) => Err(code),
            _ => Ok(()),
        }
    }

    #[test]
    fn maps_groups_and_falls_to_its_error_values_without_the_master() {
        let mut m = Cia401Module::new(10, 2);
        let mut out = Vec::new();
        m.poll(0, &mut out);
        assert_eq!(out, [nmt::heartbeat(10, nmt::state::BOOT_UP)]);
        assert_eq!(
            sdo_write(&mut m, 0x1600, 1, 0x6200_0308),
            Err(abort::CANNOT_MAP),
            "a third group it does not have"
        );
        for (i, s, v) in [
            (0x1400, 1, 0x8000_020A),
            (0x1600, 1, 0x6200_0208),
            (0x1600, 0, 1),
            (0x1400, 2, 0xFF),
            (0x1400, 1, 0x20A),
            (0x6206, 2, 0x0F),
            (0x6207, 2, 0x05),
            (0x1016, 1, (127 << 16) | 100),
        ] {
            sdo_write(&mut m, i, s, v).unwrap();
        }
        m.handle(&nmt::command(nmt::Command::Start, 10), 0, &mut out);
        m.handle(&Frame::new(0x20A, &[0xFA]), 0, &mut out);
        assert_eq!(m.io.outputs(), 0xFA00, "RPDO byte 0 is group 2");
        m.handle(&nmt::heartbeat(127, nmt::state::OPERATIONAL), 10, &mut out);
        out.clear();
        m.poll(110, &mut out);
        assert_eq!(m.io.outputs(), 0xFA00, "within the consumer time");
        m.poll(111, &mut out);
        assert_eq!(m.io.outputs(), 0xF500, "low nibble to its error values");
        assert_eq!(m.nmt_state(), nmt::state::PRE_OPERATIONAL);
        assert!(out.iter().any(|f| f.id == 0x8A), "EMCY: {out:?}");
    }
}
