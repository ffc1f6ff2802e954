//! A simulated CANopen CiA 402 drive node: NMT slave, expedited SDO server for the objects a
//! CSP (axis) or CSV (spindle) master configures, synchronous PDOs, EMCY, heartbeat producer
//! and consumer, and fault injection. The mode of operation (0x6060 = 8 or 9) and the PDO
//! mapping the master writes decide whether the node is a position or a velocity drive;
//! 0x6060 = 6 is homing mode ([`crate::homing`]: a home switch, objects 0x6098, 0x607C,
//! 0x6099, 0x609A). Digital inputs 0x60FD and outputs 0x60FE:1 in PDO2 when the master maps
//! them ([`crate::drive_io`]). No I/O of its own: the caller feeds frames and the time, and
//! sends what comes out (the `sim-can` binary does that on a SocketCAN interface; tests do it
//! in memory).

use hal::canopen::emcy::Emcy;
use hal::canopen::pdo::{OpMode, Rpdo, Tpdo};
use hal::canopen::sdo::{self, Request, abort};
use hal::canopen::{Frame, cob, nmt};

use crate::cia402_drive::{COMMUNICATION_LOST, Cia402Drive, Event};
use crate::drive_io::DriveIo;

/// Fault-injection switches.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Injection {
    /// Stop producing heartbeats (everything else continues).
    pub drop_heartbeat: bool,
    /// Stop answering anything: a hung drive.
    pub silent: bool,
    /// Send TPDOs with a wrong length (a corrupt frame as the master sees it).
    pub corrupt_pdo: bool,
}

/// Communication objects (reset to these by NMT reset).
#[derive(Clone, Copy, Debug)]
struct CommObjects {
    rpdo_cob: u32,
    rpdo_type: u8,
    rpdo_map: [u32; 2],
    rpdo_count: u8,
    tpdo_cob: u32,
    tpdo_type: u8,
    tpdo_map: [u32; 2],
    tpdo_count: u8,
    comm_cycle_us: u32,
    heartbeat_ms: u16,
    consumer: u32,
    mode: u8,
    interp_period: (u8, i8),
}

const DISABLED: u32 = 0x8000_0000;
/// Modes of operation value of homing mode (CiA 402).
const HOMING_MODE: u8 = 6;

impl CommObjects {
    /// Power-on values: PDOs unmapped and disabled, so an unconfigured drive stays quiet.
    fn defaults(id: u8) -> CommObjects {
        let n = u32::from(id);
        CommObjects {
            rpdo_cob: DISABLED | (0x200 + n),
            rpdo_type: 255,
            rpdo_map: [0; 2],
            rpdo_count: 0,
            tpdo_cob: DISABLED | (0x180 + n),
            tpdo_type: 255,
            tpdo_map: [0; 2],
            tpdo_count: 0,
            comm_cycle_us: 0,
            heartbeat_ms: 0,
            consumer: 0,
            mode: 0,
            interp_period: (4, -3),
        }
    }

    fn rpdo_active(&self, id: u8) -> bool {
        self.rpdo_cob == 0x200 + u32::from(id) && self.rpdo_count == 2 && self.rpdo_type <= 240
    }

    fn tpdo_active(&self, id: u8) -> bool {
        self.tpdo_cob == 0x180 + u32::from(id) && self.tpdo_count == 2 && self.tpdo_type <= 240
    }

    /// The layout of the RPDO (`rpdo == true`) or TPDO as mapped, if it is one we know.
    fn layout(&self, rpdo: bool) -> Option<OpMode> {
        let (map, count) = if rpdo {
            (self.rpdo_map, self.rpdo_count)
        } else {
            (self.tpdo_map, self.tpdo_count)
        };
        [OpMode::Csp, OpMode::Csv].into_iter().find(|m| {
            count == 2
                && map
                    == if rpdo {
                        m.rpdo_mapping()
                    } else {
                        m.tpdo_mapping()
                    }
        })
    }

    fn cycle_s(&self) -> f64 {
        let (v, e) = self.interp_period;
        f64::from(v) * 10f64.powi(i32::from(e))
    }
}

/// The PDO layouts this drive can be mapped to: CSP and CSV.
fn layouts(rpdo: bool) -> [[u32; 2]; 2] {
    [OpMode::Csp, OpMode::Csv].map(|m| {
        if rpdo {
            m.rpdo_mapping()
        } else {
            m.tpdo_mapping()
        }
    })
}

pub struct CanNode {
    pub id: u8,
    pub drive: Cia402Drive,
    pub inject: Injection,
    /// Its digital inputs 0x60FD (set from outside) and outputs 0x60FE:1.
    pub io: DriveIo,
    nmt: u8,
    od: CommObjects,
    latched: Option<Rpdo>,
    held: Rpdo,
    next_heartbeat_ms: u64,
    master_heartbeat_ms: Option<u64>,
    booted: bool,
}

impl CanNode {
    pub fn new(id: u8, drive: Cia402Drive) -> CanNode {
        CanNode {
            id,
            drive,
            inject: Injection::default(),
            io: DriveIo::new(id),
            nmt: nmt::state::PRE_OPERATIONAL,
            od: CommObjects::defaults(id),
            latched: None,
            held: Rpdo {
                controlword: 0,
                target_increments: 0,
            },
            next_heartbeat_ms: 0,
            master_heartbeat_ms: None,
            booted: false,
        }
    }

    pub fn nmt_state(&self) -> u8 {
        self.nmt
    }

    fn boot(&mut self, now_ms: u64, out: &mut Vec<Frame>) {
        self.od = CommObjects::defaults(self.id);
        self.io.reset_communication(self.id);
        self.drive.set_homing_mode(false);
        self.nmt = nmt::state::PRE_OPERATIONAL;
        self.latched = None;
        self.master_heartbeat_ms = None;
        self.next_heartbeat_ms = now_ms;
        out.push(nmt::heartbeat(self.id, nmt::state::BOOT_UP));
    }

    fn announce(&self, e: Option<Event>, out: &mut Vec<Frame>) {
        let emcy = match e {
            Some(Event::Fault { code }) => Emcy {
                code,
                register: 0x01,
                vendor: [0; 5],
            },
            Some(Event::FaultCleared) => Emcy {
                code: 0,
                register: 0,
                vendor: [0; 5],
            },
            None => return,
        };
        out.push(emcy.encode(self.id));
    }

    /// A drive fault from outside the drive model (fault injection).
    pub fn force_fault(&mut self, code: u16, out: &mut Vec<Frame>) {
        let e = self.drive.fault(code);
        self.announce(e, out);
    }

    /// Handles one received frame.
    pub fn handle(&mut self, f: &Frame, now_ms: u64, out: &mut Vec<Frame>) {
        let start = out.len();
        self.handle_inner(f, now_ms, out);
        if self.inject.silent {
            out.truncate(start);
        }
    }

    fn handle_inner(&mut self, f: &Frame, now_ms: u64, out: &mut Vec<Frame>) {
        let p = f.payload();
        if f.id == cob::NMT {
            if p.len() == 2 && (p[1] == 0 || p[1] == self.id) {
                self.on_nmt(p[0], now_ms, out);
            }
            return;
        }
        if self.inject.silent {
            return;
        }
        if f.id == cob::SYNC {
            self.on_sync(out);
            return;
        }
        let (code, node) = cob::split(f.id);
        let consumer_id = ((self.od.consumer >> 16) & 0x7F) as u8;
        match code {
            cob::HEARTBEAT if node == consumer_id && consumer_id != 0 => {
                self.master_heartbeat_ms = Some(now_ms);
            }
            cob::RPDO2 if node == self.id && self.nmt == nmt::state::OPERATIONAL => {
                self.io.on_rpdo2(self.id, p);
            }
            cob::RPDO1
                if node == self.id
                    && self.nmt == nmt::state::OPERATIONAL
                    && self.od.rpdo_active(self.id) =>
            {
                self.latched = Rpdo::decode(p);
            }
            cob::SDO_RX if node == self.id && self.nmt != nmt::state::STOPPED => {
                let answer = match sdo::parse_request(p) {
                    Ok(Request::Download {
                        index,
                        subindex,
                        value,
                        ..
                    }) => match self.write(index, subindex, value) {
                        Ok(()) => sdo::download_ok(self.id, index, subindex),
                        Err(code) => sdo::abort(self.id, index, subindex, code),
                    },
                    Ok(Request::Upload { index, subindex }) => match self.read(index, subindex) {
                        Ok((value, size)) => sdo::upload_ok(self.id, index, subindex, value, size),
                        Err(code) => sdo::abort(self.id, index, subindex, code),
                    },
                    Err(code) => sdo::abort(self.id, 0, 0, code),
                };
                out.push(answer);
            }
            _ => {}
        }
    }

    fn on_nmt(&mut self, cmd: u8, now_ms: u64, out: &mut Vec<Frame>) {
        match nmt::Command::from_byte(cmd) {
            Some(nmt::Command::Start) => self.nmt = nmt::state::OPERATIONAL,
            Some(nmt::Command::Stop) => self.nmt = nmt::state::STOPPED,
            Some(nmt::Command::EnterPreOperational) => self.nmt = nmt::state::PRE_OPERATIONAL,
            Some(nmt::Command::ResetNode) => {
                self.drive.restart();
                self.boot(now_ms, out);
            }
            Some(nmt::Command::ResetCommunication) => self.boot(now_ms, out),
            None => {}
        }
        if self.nmt != nmt::state::OPERATIONAL
            && self.drive.state() != hal::cia402::PowerState::Fault
        {
            // Leaving NMT operational switches the power stage off.
            self.drive.restart();
        }
    }

    fn on_sync(&mut self, out: &mut Vec<Frame>) {
        if self.nmt != nmt::state::OPERATIONAL {
            return;
        }
        if self.od.rpdo_active(self.id) {
            if let Some(r) = self.latched.take() {
                self.held = r;
            }
            let (cw, value, dt) = (
                self.held.controlword,
                self.held.target_increments,
                self.od.cycle_s(),
            );
            // The mode of operation picks the loop; a target mapped for the other mode is
            // not a target of this one (the drive holds: position where it is, speed 0).
            let layout = self.od.layout(true);
            self.drive.set_homing_mode(self.od.mode == HOMING_MODE);
            let e = if self.od.mode == HOMING_MODE {
                // Homing mode: the drive moves on its own; the target is not used.
                self.drive.cycle_homing(cw, dt)
            } else if OpMode::from_code(u32::from(self.od.mode)) == Some(OpMode::Csv) {
                let target = if layout == Some(OpMode::Csv) {
                    value
                } else {
                    0
                };
                self.drive.cycle_velocity(cw, target, dt)
            } else {
                let target = if layout == Some(OpMode::Csp) {
                    value
                } else {
                    self.drive.position_increments()
                };
                self.drive.cycle(cw, target, dt)
            };
            self.announce(e, out);
        }
        self.io.on_sync(self.id, out);
        if self.od.tpdo_active(self.id) {
            let value = match self.od.layout(false) {
                Some(OpMode::Csv) => self.drive.velocity_units(),
                _ => self.drive.position_increments(),
            };
            let mut f = Tpdo {
                statusword: self.drive.statusword(),
                position_increments: value,
            }
            .encode(self.id);
            if self.inject.corrupt_pdo {
                f.len = 3;
            }
            out.push(f);
        }
    }

    /// Time passes: heartbeat production and the consumer watch on the master.
    pub fn poll(&mut self, now_ms: u64, out: &mut Vec<Frame>) {
        if self.inject.silent {
            return; // a silent drive from the start is one that is not powered yet
        }
        if !self.booted {
            self.booted = true;
            self.boot(now_ms, out);
        }
        let hb = u64::from(self.od.heartbeat_ms);
        if hb > 0 && now_ms >= self.next_heartbeat_ms {
            self.next_heartbeat_ms = now_ms + hb;
            if !self.inject.drop_heartbeat {
                out.push(nmt::heartbeat(self.id, self.nmt));
            }
        }
        // The heartbeat consumer (0x1016) watches in operational and pre-operational alike,
        // from the first heartbeat on (CiA 301): a master that stops without clearing it
        // leaves a faulted drive in pre-operational (0x1029 error behaviour).
        let consumer_ms = u64::from(self.od.consumer & 0xFFFF);
        if let Some(last) = self.master_heartbeat_ms
            && consumer_ms > 0
            && now_ms.saturating_sub(last) > consumer_ms
        {
            self.master_heartbeat_ms = None;
            if self.nmt != nmt::state::STOPPED {
                let e = self.drive.fault(COMMUNICATION_LOST);
                self.announce(e, out);
                self.nmt = nmt::state::PRE_OPERATIONAL;
                self.latched = None;
            }
        }
    }

    /// The heartbeat consumer entry 0x1016:1 (master node id << 16 | time in ms; 0: off).
    pub fn consumer(&self) -> u32 {
        self.od.consumer
    }

    /// One line for a test: NMT state, statusword, error code, consumer entry.
    pub fn state_line(&self) -> String {
        format!(
            "state node {} nmt {:02X} statusword {:04X} error {:04X} consumer {:08X}",
            self.id,
            self.nmt,
            self.drive.statusword(),
            self.drive.error_code(),
            self.od.consumer
        )
    }

    /// 0x1600:0 / 0x1A00:0, the number of mapped entries of the RPDO (`rpdo`) or TPDO.
    fn write_map_count(&mut self, rpdo: bool, v: u32) -> Result<(), u32> {
        let od = &mut self.od;
        let (cob_id, map, count) = if rpdo {
            (od.rpdo_cob, od.rpdo_map, &mut od.rpdo_count)
        } else {
            (od.tpdo_cob, od.tpdo_map, &mut od.tpdo_count)
        };
        if cob_id & DISABLED == 0 {
            return Err(abort::DEVICE_STATE);
        }
        let known = layouts(rpdo).contains(&map);
        match v {
            0 => *count = 0,
            2 if known => *count = 2,
            2 => return Err(abort::CANNOT_MAP),
            _ => return Err(abort::VALUE_RANGE),
        }
        Ok(())
    }

    /// 0x1600:1..2 / 0x1A00:1..2, mapping entry `i` of the RPDO (`rpdo`) or TPDO.
    fn write_map_entry(&mut self, rpdo: bool, i: usize, v: u32) -> Result<(), u32> {
        let od = &mut self.od;
        let (count, map) = if rpdo {
            (od.rpdo_count, &mut od.rpdo_map)
        } else {
            (od.tpdo_count, &mut od.tpdo_map)
        };
        // Mapping entries change only with the PDO invalid and its count at 0.
        let cob_id = if rpdo { od.rpdo_cob } else { od.tpdo_cob };
        if count != 0 || cob_id & DISABLED == 0 {
            return Err(abort::DEVICE_STATE);
        }
        // This drive supports only the CSP and CSV layouts; say so instead of misbehaving.
        if !layouts(rpdo).iter().any(|want| v == want[i]) {
            return Err(abort::CANNOT_MAP);
        }
        map[i] = v;
        Ok(())
    }

    fn write(&mut self, index: u16, sub: u8, v: u32) -> Result<(), u32> {
        if let Some(r) = self.io.write(index, sub, v) {
            return r;
        }
        let od = &mut self.od;
        match (index, sub) {
            // CiA 301: a valid PDO's COB-ID changes only through invalid (bit 31 set first).
            (0x1400, 1) if od.rpdo_cob & DISABLED == 0 && v & DISABLED == 0 && v != od.rpdo_cob => {
                return Err(abort::VALUE_RANGE);
            }
            (0x1800, 1) if od.tpdo_cob & DISABLED == 0 && v & DISABLED == 0 && v != od.tpdo_cob => {
                return Err(abort::VALUE_RANGE);
            }
            (0x1400, 1) => od.rpdo_cob = v,
            (0x1400, 2) if v <= 255 => od.rpdo_type = v as u8,
            (0x1800, 1) => od.tpdo_cob = v,
            (0x1800, 2) if v <= 255 => od.tpdo_type = v as u8,
            (0x1600 | 0x1A00, 0) => self.write_map_count(index == 0x1600, v)?,
            (0x1600 | 0x1A00, 1 | 2) => {
                self.write_map_entry(index == 0x1600, usize::from(sub - 1), v)?
            }
            (0x6060, 0) if OpMode::from_code(v).is_some() || v == u32::from(HOMING_MODE) => {
                od.mode = v as u8;
                self.drive.set_homing_mode(od.mode == HOMING_MODE);
            }
            // The homing objects (crate::homing).
            (0x6098, 0) if v <= 0xFF => self.drive.homer.objects.method = v as u8 as i8,
            (0x607C, 0) => self.drive.homer.objects.offset = v as i32,
            (0x6099, 1) => self.drive.homer.objects.search_speed = v,
            (0x6099, 2) => self.drive.homer.objects.zero_speed = v,
            (0x609A, 0) => self.drive.homer.objects.accel = v,
            (0x6060, 0) => return Err(abort::VALUE_RANGE),
            (0x60C2, 1) if v <= 255 => od.interp_period.0 = v as u8,
            (0x60C2, 2) if v <= 255 => od.interp_period.1 = v as u8 as i8,
            (0x1006, 0) => od.comm_cycle_us = v,
            (0x1017, 0) if v <= 0xFFFF => od.heartbeat_ms = v as u16,
            (0x1016, 1) => od.consumer = v,
            (0x6065, 0) => self.drive.set_window_increments(v),
            (0x1000 | 0x6041 | 0x6064 | 0x606C | 0x6061 | 0x603F, 0) => {
                return Err(abort::READ_ONLY);
            }
            (
                0x1400 | 0x1800 | 0x1600 | 0x1A00 | 0x60C2 | 0x1017 | 0x1016 | 0x6060 | 0x1006
                | 0x6065 | 0x6098 | 0x607C | 0x6099 | 0x609A,
                _,
            ) => {
                return Err(abort::NO_SUBINDEX);
            }
            _ => return Err(abort::NO_OBJECT),
        }
        Ok(())
    }

    fn read(&self, index: u16, sub: u8) -> Result<(u32, u8), u32> {
        if let Some(r) = self.io.read(index, sub) {
            return r;
        }
        let od = &self.od;
        Ok(match (index, sub) {
            (0x1000, 0) => (0x0002_0192, 4), // CiA 402 device, servo
            (0x1006, 0) => (od.comm_cycle_us, 4),
            (0x1017, 0) => (u32::from(od.heartbeat_ms), 2),
            (0x1016, 1) => (od.consumer, 4),
            (0x1400, 1) => (od.rpdo_cob, 4),
            (0x1800, 1) => (od.tpdo_cob, 4),
            (0x1600, 0) => (u32::from(od.rpdo_count), 1),
            (0x1A00, 0) => (u32::from(od.tpdo_count), 1),
            (0x6060 | 0x6061, 0) => (u32::from(od.mode), 1),
            (0x6041, 0) => (u32::from(self.drive.statusword()), 2),
            (0x6064, 0) => (self.drive.position_increments() as u32, 4),
            (0x606C, 0) => (self.drive.velocity_units() as u32, 4),
            (0x6065, 0) => (self.drive.window_increments(), 4),
            (0x603F, 0) => (u32::from(self.drive.error_code()), 2),
            (0x6098, 0) => (u32::from(self.drive.homer.objects.method as u8), 1),
            (0x607C, 0) => (self.drive.homer.objects.offset as u32, 4),
            (0x6099, 1) => (self.drive.homer.objects.search_speed, 4),
            (0x6099, 2) => (self.drive.homer.objects.zero_speed, 4),
            (0x609A, 0) => (self.drive.homer.objects.accel, 4),
            _ => return Err(abort::NO_OBJECT),
        })
    }
}
