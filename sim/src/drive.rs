//! A servo drive model: position loop with proportional gain Kv and a velocity limit.
//!
//! The actual position lags the setpoint as a real position loop does: in steady motion at
//! speed v the following error is v / Kv (at Kv = 30 1/s and 100 mm/s, 3.3 mm).

use hal::DriveState;

#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SimDriveParams {
    /// Position-loop gain, 1/s.
    pub kv_per_s: f64,
    /// Velocity limit of the drive, mm/s.
    pub v_max_mm_s: f64,
    /// Following-error window (CiA 402 0x6065), mm; beyond it the drive faults.
    pub following_window_mm: f64,
}

impl Default for SimDriveParams {
    fn default() -> Self {
        SimDriveParams {
            kv_per_s: 30.0,
            v_max_mm_s: 1000.0,
            following_window_mm: 50.0,
        }
    }
}

/// Internal integration steps per cycle (the drive's own loop runs faster than 4 ms).
const SUBSTEPS: u32 = 8;

/// The position loop: where a drive at `position_mm` is after `dt_s` chasing `setpoint_mm`.
pub fn follow(params: &SimDriveParams, position_mm: f64, setpoint_mm: f64, dt_s: f64) -> f64 {
    let h = dt_s / SUBSTEPS as f64;
    let mut p = position_mm;
    for _ in 0..SUBSTEPS {
        let v = (params.kv_per_s * (setpoint_mm - p)).clamp(-params.v_max_mm_s, params.v_max_mm_s);
        p += v * h;
    }
    p
}

#[derive(Clone, Debug)]
pub struct SimDrive {
    pub params: SimDriveParams,
    position_mm: f64,
    state: DriveState,
    /// Cycles left in the enable sequence.
    enabling: u8,
}

impl SimDrive {
    pub fn new(params: SimDriveParams, position_mm: f64) -> Self {
        SimDrive {
            params,
            position_mm,
            state: DriveState::Disabled,
            enabling: 0,
        }
    }

    pub fn position_mm(&self) -> f64 {
        self.position_mm
    }

    pub fn state(&self) -> DriveState {
        self.state
    }

    pub fn enable(&mut self) {
        if self.state == DriveState::Disabled {
            // Shutdown → switched on → operation enabled takes a few cycles on real drives.
            self.state = DriveState::Enabling;
            self.enabling = 3;
        }
    }

    pub fn reset(&mut self) {
        if self.state == DriveState::Fault {
            self.state = DriveState::Disabled;
        }
    }

    /// Redefines the reported position (homing): the position `trigger_mm` becomes
    /// `reference_mm`; the motor does not move.
    pub fn shift_reference(&mut self, trigger_mm: f64, reference_mm: f64) {
        self.position_mm += reference_mm - trigger_mm;
    }

    /// Switches the power stage off (the safe state after a fault stop); a faulted drive
    /// stays faulted until reset.
    pub fn disable(&mut self) {
        if self.state != DriveState::Fault {
            self.state = DriveState::Disabled;
        }
    }

    pub fn force_fault(&mut self) {
        self.state = DriveState::Fault;
    }

    /// Advances the drive by `dt_s` toward `setpoint_mm`.
    pub fn step(&mut self, setpoint_mm: f64, dt_s: f64) {
        match self.state {
            DriveState::Enabling => {
                self.enabling = self.enabling.saturating_sub(1);
                if self.enabling == 0 {
                    self.state = DriveState::Operational;
                }
                return;
            }
            DriveState::Operational => {}
            _ => return,
        }
        self.position_mm = follow(&self.params, self.position_mm, setpoint_mm, dt_s);
        if (setpoint_mm - self.position_mm).abs() > self.params.following_window_mm {
            self.state = DriveState::Fault;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn lags_then_settles() {
        let mut d = SimDrive::new(SimDriveParams::default(), 0.0);
        d.enable();
        for _ in 0..3 {
            d.step(0.0, 0.004);
        }
        assert_eq!(d.state(), DriveState::Operational);
        // Ramp at 100 mm/s: steady following error ≈ v/Kv = 3.33 mm.
        let mut sp = 0.0;
        for _ in 0..250 {
            sp += 100.0 * 0.004;
            d.step(sp, 0.004);
        }
        let fe = sp - d.position_mm();
        assert!((fe - 100.0 / 30.0).abs() < 0.3, "following error {fe}");
        for _ in 0..250 {
            d.step(sp, 0.004);
        }
        assert!((sp - d.position_mm()).abs() < 1e-3);
    }

    #[test]
    fn following_window_faults() {
        let mut d = SimDrive::new(SimDriveParams::default(), 0.0);
        d.enable();
        for _ in 0..3 {
            d.step(0.0, 0.004);
        }
        d.step(100.0, 0.004);
        assert_eq!(d.state(), DriveState::Fault);
    }
}
