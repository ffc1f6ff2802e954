//! Phase *inputs and outputs* (docs/io.md): after each bus exchange the inputs it read act in
//! this tick (the e-stop chain and the limit switches start the fault stop, the door and the
//! buttons hold or resume, an M function's confirmation lets its block start); before each
//! exchange the outputs are made from the program's M functions, the spindle, pulses and
//! forcing, and fall to their safe values on a fault, an e-stop or a shutdown.

use hal::io::{IoBits, MAX_IO};
use hal::{BusFault, FaultReason};
use kernel::interp::InterpState;
use kernel::plc::CellId;
use kernel::units::MAX_AXES;

use super::{MachineState, RtCore};

/// What each input and output does, as bit masks (bit k: input or output k). Built once from
/// the configuration; `Copy`, so the tick reads it without allocating.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct IoFunctions {
    pub inputs: usize,
    pub outputs: usize,
    /// Inputs whose wire reads the opposite of their function's sense.
    pub invert: u64,
    /// The e-stop chain: every one must read 1.
    pub estop: u64,
    /// Limit switches per axis (1: reached).
    pub limit_neg: [u64; MAX_AXES],
    pub limit_pos: [u64; MAX_AXES],
    /// Home switches per axis (1: pressed).
    pub home: [u64; MAX_AXES],
    pub feed_hold: u64,
    pub cycle_start: u64,
    /// Door closed (1).
    pub door: u64,
    /// Alarm inputs (1: active), shown only, or stopping the machine.
    pub alarm_warning: u64,
    pub alarm_fault: u64,
    /// Probe inputs (1: touching), read by probing moves.
    pub probe: u64,
    /// How long a block waits for input k to confirm its M function, 4 ms steps.
    pub wait_steps: [u32; MAX_IO],
    /// Outputs' safe values (bit set: 1).
    pub safe: u64,
    /// Outputs the program switches with M functions.
    pub program: u64,
    pub spindle_enable: u64,
    pub spindle_cw: u64,
    pub spindle_ccw: u64,
    /// Length of output k's pulse, 4 ms steps (0: not a pulse output).
    pub pulse_steps: [u32; MAX_IO],
}

impl Default for IoFunctions {
    fn default() -> Self {
        IoFunctions {
            inputs: 0,
            outputs: 0,
            invert: 0,
            estop: 0,
            limit_neg: [0; MAX_AXES],
            limit_pos: [0; MAX_AXES],
            home: [0; MAX_AXES],
            feed_hold: 0,
            cycle_start: 0,
            door: 0,
            alarm_warning: 0,
            alarm_fault: 0,
            probe: 0,
            wait_steps: [0; MAX_IO],
            safe: 0,
            program: 0,
            spindle_enable: 0,
            spindle_cw: 0,
            spindle_ccw: 0,
            pulse_steps: [0; MAX_IO],
        }
    }
}

/// The inputs and outputs as the operator sees them (part of the snapshot).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct IoStatus {
    /// Inputs in their function's sense (after `invert`), bit k: input k.
    pub inputs: IoBits,
    /// Outputs as sent this tick.
    pub outputs: IoBits,
    /// Forced outputs (commissioning) and the values they are forced to.
    pub forced: IoBits,
    pub forced_values: IoBits,
    /// The e-stop chain is open.
    pub estop_open: bool,
    /// The door is open.
    pub door_open: bool,
    /// Limit switches reached (bit k: input k).
    pub limits: IoBits,
    /// Limit switches the operator has acknowledged with Reset: only a jog away from them
    /// moves until they release.
    pub limits_acknowledged: IoBits,
    /// Alarm inputs active.
    pub alarms: IoBits,
    /// Inputs a block waits for now, and those whose wait timed out (the program holds).
    pub waiting: IoBits,
    pub wait_timed_out: IoBits,
    /// Presses of the cycle start button (the controller starts the selected program on
    /// an idle machine).
    pub cycle_start_presses: u32,
}

/// The I/O state the tick keeps between ticks.
#[derive(Clone, Copy, Debug)]
pub(super) struct IoLogic {
    pub(super) f: IoFunctions,
    /// Inputs in their function's sense, last tick.
    pub(super) last: u64,
    /// The outputs' pulses: steps left per output, and the last pulse count seen.
    pub(super) pulse_left: [u32; MAX_IO],
    pub(super) pulse_seq: u16,
    /// Steps the current input wait has lasted.
    pub(super) wait_steps: u32,
}

impl IoLogic {
    pub(super) fn new(f: IoFunctions) -> IoLogic {
        IoLogic {
            f,
            last: 0,
            pulse_left: [0; MAX_IO],
            pulse_seq: 0,
            wait_steps: 0,
        }
    }

    fn limits(&self) -> u64 {
        self.f
            .limit_neg
            .iter()
            .chain(&self.f.limit_pos)
            .fold(0, |m, &b| m | b)
    }

    /// The axis and side of limit input `k`.
    fn limit_of(&self, k: usize) -> Option<(usize, bool)> {
        let bit = 1u64 << k;
        (0..MAX_AXES).find_map(|a| {
            if self.f.limit_pos[a] & bit != 0 {
                Some((a, true))
            } else if self.f.limit_neg[a] & bit != 0 {
                Some((a, false))
            } else {
                None
            }
        })
    }
}

fn lowest(bits: u64) -> u8 {
    bits.trailing_zeros() as u8
}

impl RtCore {
    /// The inputs the last exchange read act now: the fault stop for an open e-stop chain,
    /// a newly reached limit switch or a fault alarm input; the door and the buttons.
    pub(super) fn inputs(&mut self) {
        let f = self.io_logic.f;
        let now = (self.io.fb.inputs.0 ^ f.invert) & IoBits::first(f.inputs).0;
        let rose = now & !self.io_logic.last;
        self.io_logic.last = now;
        let st = &mut self.snap.io;
        st.inputs = IoBits(now);
        st.estop_open = now & f.estop != f.estop;
        st.door_open = now & f.door != f.door;
        st.limits = IoBits(now & self.io_logic.limits());
        // A limit that released needs no acknowledgement any more.
        st.limits_acknowledged.0 &= st.limits.0;
        st.alarms = IoBits(now & (f.alarm_warning | f.alarm_fault));
        // While the drives are being enabled (power-on, after Reset) nothing moves and the
        // inputs of modules still booting read 0: an open chain keeps the outputs safe
        // (`outputs`) and faults once enabling ends.
        if self.snap.state == MachineState::Enabling {
            self.buttons(rose, now);
            return;
        }
        if st.estop_open {
            let open = f.estop & !now;
            self.input_fault(
                None,
                FaultReason::EmergencyStop {
                    input: lowest(open),
                },
            );
        }
        let fresh = self.snap.io.limits.0 & !self.snap.io.limits_acknowledged.0;
        if fresh != 0 {
            let k = lowest(fresh) as usize;
            if let Some((axis, positive)) = self.io_logic.limit_of(k) {
                let reason = FaultReason::LimitSwitch {
                    positive,
                    input: k as u8,
                };
                self.input_fault(Some(axis as u8), reason);
            }
        }
        if now & f.alarm_fault != 0 {
            let k = lowest(now & f.alarm_fault);
            self.input_fault(None, FaultReason::InputAlarm { input: k });
        }
        self.buttons(rose, now);
    }

    /// A fault of the machine's own inputs: the fault stop, as for a drive fault, except that
    /// every axis (the named one too) still follows and brakes.
    fn input_fault(&mut self, axis: Option<u8>, reason: FaultReason) {
        if self.snap.alarm.fault.is_none() {
            self.fault(BusFault {
                axis,
                node: None,
                reason,
            });
        }
    }

    /// Feed hold and cycle start presses; the door holds a running program.
    fn buttons(&mut self, rose: u64, now: u64) {
        let f = self.io_logic.f;
        if rose & f.feed_hold != 0 && self.job.active != 0 {
            self.motion.interp.hold();
        }
        if self.snap.io.door_open && self.job.active != 0 {
            self.motion.interp.hold();
        }
        if rose & f.cycle_start != 0 {
            self.snap.io.cycle_start_presses = self.snap.io.cycle_start_presses.wrapping_add(1);
            let held = matches!(self.snap.state, MachineState::Hold);
            if held && !self.snap.io.door_open && now & f.feed_hold == 0 {
                self.resume_job();
            }
        }
    }

    /// Resume after a hold or a program stop; a wait that timed out waits again.
    pub(super) fn resume_job(&mut self) {
        self.snap.io.wait_timed_out = IoBits::NONE;
        self.io_logic.wait_steps = 0;
        // During an automatic tool change only the changer resumes the program.
        if self.changer.retry() {
            return;
        }
        self.motion.interp.resume();
    }

    /// Before the interpolator's step: tell it whether the inputs its next block waits for
    /// read 1; hold with an alarm when they have not within their time.
    pub(super) fn input_waits(&mut self) {
        let wait = self.motion.out.spindle.outputs.wait;
        let now = self.io_logic.last;
        self.motion.interp.set_inputs_confirmed(now & wait == wait);
        if !self.motion.interp.waiting_for_inputs()
            || self.motion.interp.state() != InterpState::Running
        {
            self.io_logic.wait_steps = 0;
            self.snap.io.waiting = IoBits::NONE;
            return;
        }
        let missing = wait & !now;
        self.snap.io.waiting = IoBits(missing);
        self.io_logic.wait_steps += 1;
        if missing != 0 && self.io_logic.wait_steps > self.wait_limit_steps(missing) {
            self.snap.io.wait_timed_out = IoBits(missing);
            self.motion.interp.hold();
        }
    }

    /// How long a wait for the inputs `missing` may last: the longest `timeout_ms` among
    /// them, in 4 ms steps.
    pub(super) fn wait_limit_steps(&self, missing: u64) -> u32 {
        (0..MAX_IO)
            .filter(|&k| missing & (1 << k) != 0)
            .map(|k| self.io_logic.f.wait_steps[k])
            .max()
            .unwrap_or(0)
    }

    /// This tick's outputs: the program's M functions, the spindle, pulses, forcing; the
    /// safe values on a fault, an open e-stop chain or a shutdown.
    pub(super) fn outputs(&mut self) {
        let f = self.io_logic.f;
        let prog = self.motion.out.spindle.outputs;
        let stopped = self.job.spindle_off && self.motion.interp.state() == InterpState::Idle;
        // The changer's outputs are its own, not the program's M functions'.
        let ch = &self.changer;
        let mut out = if stopped {
            0
        } else {
            (prog.on & f.program & !ch.owned) | ch.on
        };
        let rpm = self.io.cmd.spindle_rpm;
        if rpm != 0.0 {
            out |= f.spindle_enable
                | if rpm > 0.0 {
                    f.spindle_cw
                } else {
                    f.spindle_ccw
                };
        }
        out |= self.pulses(prog.pulse, prog.pulse_seq);
        let st = &mut self.snap.io;
        out = (out & !st.forced.0) | (st.forced_values.0 & st.forced.0);
        let unsafe_now = self.snap.alarm.fault.is_some()
            || self.snap.alarm.kr_fault.is_some()
            || st.estop_open
            || self.lifecycle.shutting_down;
        if unsafe_now {
            out = f.safe;
        }
        out &= IoBits::first(f.outputs).0;
        st.outputs = IoBits(out);
        let inputs = st.inputs.0;
        // The PLC area shows both (docs/plc.md): bit patterns of two double words each.
        let plc = &mut self.logic.plc;
        plc.set_act(CellId::IoInLo, inputs as u32 as i32);
        plc.set_act(CellId::IoInHi, (inputs >> 32) as u32 as i32);
        plc.set_act(CellId::IoOutLo, out as u32 as i32);
        plc.set_act(CellId::IoOutHi, (out >> 32) as u32 as i32);
        self.io.cmd.outputs = IoBits(out);
        self.io.bus_cmd.outputs = IoBits(out);
    }

    /// Outputs pulsing now: a new pulse count starts the pulses of the block's outputs.
    fn pulses(&mut self, pulse: u64, seq: u16) -> u64 {
        if seq != self.io_logic.pulse_seq {
            self.io_logic.pulse_seq = seq;
            self.start_pulses(pulse);
        }
        let l = &mut self.io_logic;
        let mut on = 0;
        for (k, left) in l.pulse_left.iter_mut().enumerate() {
            if *left > 0 {
                *left -= 1;
                on |= 1 << k;
            }
        }
        on
    }

    /// The outputs of `pulse` start a pulse of their configured length.
    pub(super) fn start_pulses(&mut self, pulse: u64) {
        let l = &mut self.io_logic;
        for k in 0..MAX_IO {
            if pulse & (1 << k) != 0 {
                l.pulse_left[k] = l.f.pulse_steps[k].max(1);
            }
        }
    }

    /// Forcing an output (commissioning): `Some(value)` forces it, `None` releases it.
    pub(super) fn force_output(&mut self, output: u8, value: Option<bool>) {
        let k = usize::from(output);
        if k >= self.io_logic.f.outputs {
            return;
        }
        let st = &mut self.snap.io;
        st.forced.set(k, value.is_some());
        st.forced_values.set(k, value.unwrap_or(false));
    }

    /// Reset: forcing ends; limit switches still reached are acknowledged (a jog away from
    /// them may move). Refused while the e-stop chain is open, unless a bus fault is in force:
    /// then the inputs may be stale (a module that never booted reads 0) and only the reset
    /// of the bus can bring them back; the chain is judged again once enabling ends.
    pub(super) fn io_reset(&mut self) -> bool {
        if self.snap.io.estop_open && !bus_fault(&self.snap) {
            return false;
        }
        let st = &mut self.snap.io;
        st.forced = IoBits::NONE;
        st.forced_values = IoBits::NONE;
        st.limits_acknowledged = st.limits;
        st.wait_timed_out = IoBits::NONE;
        true
    }

    /// Whether a jog of `axis` toward `target_mm` from `here_mm` moves into a limit switch
    /// that is still reached (only a jog away from it is allowed).
    pub(super) fn jog_into_limit(&self, axis: usize, here_mm: f64, target_mm: f64) -> bool {
        let reached = self.snap.io.limits.0;
        let f = &self.io_logic.f;
        (target_mm > here_mm && reached & f.limit_pos[axis] != 0)
            || (target_mm < here_mm && reached & f.limit_neg[axis] != 0)
    }

    /// Whether a limit switch is reached (no program may start).
    pub(super) fn any_limit(&self) -> bool {
        self.snap.io.limits.0 != 0
    }

    /// A home switch configured as an input for `axis` (reference runs by the controller).
    pub(super) fn home_input(&self, axis: usize) -> Option<bool> {
        let mask = self.io_logic.f.home.get(axis).copied().unwrap_or(0);
        (mask != 0).then_some(self.io_logic.last & mask != 0)
    }
}

/// A fault of the bus or a drive (not of the machine's inputs) is in force.
pub fn bus_fault(s: &super::Snapshot) -> bool {
    s.alarm.fault.is_some_and(|f| !f.reason.is_input())
}
