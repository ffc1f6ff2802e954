//! Homing mode (CiA 402 mode 6) of the simulated drive: a home switch at a configurable
//! position, the homing objects 0x6098 (method), 0x607C (home offset), 0x6099:1/2 (speeds),
//! 0x609A (acceleration), started by controlword bit 4 and reported by statusword bits 10
//! (target reached: the drive stands), 12 (homing attained) and 13 (homing error).
//!
//! Methods (as this simulator reads CiA 402; docs/buses.md#homing):
//! - 19: the home switch is active on the positive side of its edge. Off the switch the drive
//!   searches in the positive direction at 0x6099:1; on it (or once it reaches it) it leaves
//!   it in the negative direction at 0x6099:2; the edge is the home position.
//! - 21: the same with the switch active on the negative side (search in the negative
//!   direction, leave it in the positive one).
//! - 35, 37: the current position is the home position (no motion).
//!
//! At the home position the position actual value becomes the home offset 0x607C (the
//! coordinates shift; the switch stays where it is physically). Any other method, or a
//! drive without a switch, ends at once with the homing error bit.

use hal::cia402::sw;

/// The homing objects, drive units (increments, increments/s, increments/s²).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct HomingObjects {
    pub method: i8,
    pub offset: i32,
    pub search_speed: u32,
    pub zero_speed: u32,
    pub accel: u32,
}

impl Default for HomingObjects {
    fn default() -> Self {
        HomingObjects {
            method: 21,
            offset: 0,
            search_speed: 10_000,
            zero_speed: 1_000,
            accel: 100_000,
        }
    }
}

#[derive(Clone, Copy, Debug, PartialEq)]
enum Stage {
    /// Not started since entering homing mode, or interrupted and standing.
    Idle,
    /// Moving toward the switch in direction `dir` (±1).
    Search {
        dir: f64,
    },
    /// On the switch, leaving it in direction `dir`.
    Zero {
        dir: f64,
    },
    /// Braking to rest; `attained`: the home position was found.
    Stopping {
        attained: bool,
    },
    Attained,
    Error,
}

/// The reference run of one drive.
#[derive(Clone, Debug)]
pub struct Homer {
    pub objects: HomingObjects,
    stage: Stage,
    velocity_mm_s: f64,
    last_start: bool,
}

impl Default for Homer {
    fn default() -> Self {
        Homer {
            objects: HomingObjects::default(),
            stage: Stage::Idle,
            velocity_mm_s: 0.0,
            last_start: false,
        }
    }
}

/// Where the drive and its switch are, in the drive's coordinates (mm).
pub struct Axis<'a> {
    pub position_mm: &'a mut f64,
    pub switch_mm: &'a mut Option<f64>,
    pub increments_per_mm: f64,
}

impl Homer {
    /// Leaves the reference run (mode changed, power stage off): nothing started, at rest.
    pub fn reset(&mut self) {
        self.stage = Stage::Idle;
        self.velocity_mm_s = 0.0;
        self.last_start = false;
    }

    /// Homing bits of the statusword (10, 12, 13).
    pub fn status_bits(&self) -> u16 {
        match self.stage {
            Stage::Idle => sw::TARGET_REACHED,
            Stage::Search { .. } | Stage::Zero { .. } | Stage::Stopping { .. } => 0,
            Stage::Attained => sw::TARGET_REACHED | sw::HOMING_ATTAINED,
            Stage::Error => sw::TARGET_REACHED | sw::HOMING_ERROR,
        }
    }

    fn active(method: i8, position_mm: f64, switch_mm: f64) -> bool {
        if method == 19 {
            position_mm >= switch_mm
        } else {
            position_mm <= switch_mm
        }
    }

    /// The first stage of a run started at `a`.
    fn begin(&self, a: &mut Axis) -> Stage {
        let m = self.objects.method;
        if m == 35 || m == 37 {
            self.home_here(a, *a.position_mm);
            return Stage::Attained;
        }
        let (Some(switch), true) = (*a.switch_mm, m == 19 || m == 21) else {
            return Stage::Error;
        };
        let toward = if m == 19 { 1.0 } else { -1.0 };
        if Self::active(m, *a.position_mm, switch) {
            Stage::Zero { dir: -toward }
        } else {
            Stage::Search { dir: toward }
        }
    }

    /// The home position `home_mm` (drive coordinates) becomes the home offset.
    fn home_here(&self, a: &mut Axis, home_mm: f64) {
        let shift = f64::from(self.objects.offset) / a.increments_per_mm - home_mm;
        *a.position_mm += shift;
        if let Some(s) = a.switch_mm.as_mut() {
            *s += shift;
        }
    }

    /// One cycle in homing mode with the power stage enabled; `start`: controlword bit 4.
    pub fn cycle(&mut self, start: bool, a: &mut Axis, dt_s: f64) {
        if start && !self.last_start {
            self.stage = self.begin(a);
        } else if !start && matches!(self.stage, Stage::Search { .. } | Stage::Zero { .. }) {
            self.stage = Stage::Stopping { attained: false };
        }
        self.last_start = start;
        let inc = a.increments_per_mm;
        let o = self.objects;
        let target_v = match self.stage {
            Stage::Search { dir } => dir * f64::from(o.search_speed) / inc,
            Stage::Zero { dir } => dir * f64::from(o.zero_speed) / inc,
            _ => 0.0,
        };
        let dv = f64::from(o.accel) / inc * dt_s;
        self.velocity_mm_s += (target_v - self.velocity_mm_s).clamp(-dv, dv);
        *a.position_mm += self.velocity_mm_s * dt_s;
        let m = o.method;
        match (self.stage, *a.switch_mm) {
            (Stage::Search { dir }, Some(s)) if Self::active(m, *a.position_mm, s) => {
                self.stage = Stage::Zero { dir: -dir };
            }
            (Stage::Zero { .. }, Some(s)) if !Self::active(m, *a.position_mm, s) => {
                self.home_here(a, s);
                self.stage = Stage::Stopping { attained: true };
            }
            (Stage::Stopping { attained }, _) if self.velocity_mm_s == 0.0 => {
                self.stage = if attained {
                    Stage::Attained
                } else {
                    Stage::Idle
                };
            }
            _ => {}
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn run(method: i8, start_mm: f64, switch: Option<f64>) -> (Homer, f64, Option<f64>, u32) {
        let mut h = Homer {
            objects: HomingObjects {
                method,
                offset: 20_000, // 2 mm at 10000 increments/mm
                search_speed: 100_000,
                zero_speed: 10_000,
                accel: 1_000_000,
            },
            ..Homer::default()
        };
        let (mut pos, mut sw_mm) = (start_mm, switch);
        let mut cycles = 0;
        for _ in 0..10_000 {
            let mut a = Axis {
                position_mm: &mut pos,
                switch_mm: &mut sw_mm,
                increments_per_mm: 10_000.0,
            };
            h.cycle(true, &mut a, 0.004);
            cycles += 1;
            if h.status_bits() & sw::TARGET_REACHED != 0 {
                break;
            }
        }
        (h, pos, sw_mm, cycles)
    }

    #[test]
    fn finds_the_switch_edge_from_either_side_and_applies_the_offset() {
        // Off the switch (method 21: active below -5): search down at 10 mm/s, leave at 1.
        let (h, pos, sw_mm, cycles) = run(21, 0.0, Some(-5.0));
        assert_eq!(h.status_bits(), sw::TARGET_REACHED | sw::HOMING_ATTAINED);
        assert!(cycles > 100, "it moved: {cycles}");
        // The edge is now 2 mm (the offset); the drive stands just past it (braking at
        // 100 mm/s² from 1 mm/s: 0.005 mm).
        assert_eq!(sw_mm, Some(2.0));
        assert!(pos > 2.0 && pos < 2.0 + 0.01, "{pos}");
        // On the switch already (method 19: active above -5): leave it only.
        let (h, pos, _, _) = run(19, 0.0, Some(-5.0));
        assert_eq!(h.status_bits(), sw::TARGET_REACHED | sw::HOMING_ATTAINED);
        assert!(pos < 2.0 && pos > 2.0 - 0.01, "{pos}");
        // The current position (37): no motion.
        let (h, pos, _, cycles) = run(37, 7.0, None);
        assert_eq!(h.status_bits(), sw::TARGET_REACHED | sw::HOMING_ATTAINED);
        assert_eq!((pos, cycles), (2.0, 1));
        // No switch, or a method it does not know: homing error.
        for (m, s) in [(21, None), (1, Some(-5.0))] {
            let (h, _, _, _) = run(m, 0.0, s);
            assert_eq!(h.status_bits(), sw::TARGET_REACHED | sw::HOMING_ERROR);
        }
    }
}
