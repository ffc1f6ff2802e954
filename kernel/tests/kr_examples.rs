//! KŘR (SPEC §6) with the manual's worked examples and hand-computed AKRR_ACT_* values.

use kernel::block::SpindleDir;
use kernel::constants::Constants;
use kernel::kr::config::gear_for_m_code;
use kernel::kr::{
    ControllingAxis, Gear, Kr, KrConfig, KrConfigError, KrFault, KrInput, KrOutput, KrVersion,
    Motion, ProgramSpindle, RadiusInput,
};
use kernel::plc::{CellId, PlcArea, cntr};

/// Gear 1 (M41): P 500 rpm, U 7FFFh. Gear 2 (M44): P 2000 rpm, U 6000h.
fn gears() -> Vec<Gear> {
    vec![
        Gear {
            max_rpm: 500.0,
            output_range: 0x7FFF,
            m_code: Some(41),
        },
        Gear {
            max_rpm: 2000.0,
            output_range: 0x6000,
            m_code: Some(44),
        },
    ]
}

/// A lathe: X (axis 1, diameter) controls KŘR (R67 = 1), Z is axis 2.
fn lathe(r329: f64, r580: f64) -> Kr {
    Kr::new(config(&lathe_constants(1.0, r329, r580), gears()).unwrap())
}

/// The lathe's constants: R0 = 1 (X), R1 = 3 (Z), R2 = 0 (no third axis).
fn lathe_constants(r67: f64, r329: f64, r580: f64) -> Constants {
    let mut c = Constants::new();
    c.set(0, 1.0);
    c.set(1, 3.0);
    c.set(2, 0.0);
    c.set(67, r67);
    c.set(329, r329);
    c.set(580, r580);
    c
}

fn config(c: &Constants, gears: Vec<Gear>) -> Result<KrConfig, KrConfigError> {
    KrConfig::from_constants(c, RadiusInput::Diameter, gears)
}

#[test]
fn config_reads_the_constants_and_the_gears() {
    let k = config(&lathe_constants(1.0, 0.3, 0.001), gears()).unwrap();
    assert_eq!(k.controlling_axis, 0);
    assert_eq!(k.version, KrVersion::V2);
    assert!(k.s_word.swap_g96_g97 && k.s_word.s_in_m_min);
    assert_eq!(k.gear_for_m(44), Some(2));
    assert_eq!(k.gear_for_m(42), None);
    // Without a table the convention M41..M44 = ranges 1..4 holds.
    assert_eq!(gear_for_m_code(&[], 43), Some(3));
    assert_eq!(gear_for_m_code(&[], 45), None);
    assert_eq!(k.gear(0).unwrap().max_rpm, 500.0);
    assert!(k.gear(3).is_none());
    // Z (code 3) is the second axis of this lathe.
    assert_eq!(
        config(&lathe_constants(3.0, 0.0, 0.0), gears())
            .unwrap()
            .controlling_axis,
        1
    );
}

#[test]
fn config_refuses_bad_r67() {
    let bad = |r67| config(&lathe_constants(r67, 0.0, 0.0), gears());
    assert_eq!(bad(0.0), Err(KrConfigError::R67(0.0)));
    // Y (code 2) is not an axis of this lathe.
    assert_eq!(bad(2.0), Err(KrConfigError::R67(2.0)));
    assert_eq!(bad(1.5), Err(KrConfigError::R67(1.5)));
    assert_eq!(bad(10.0), Err(KrConfigError::R67(10.0)));
}

#[test]
fn config_refuses_bad_gears() {
    let c = lathe_constants(3.0, 0.0, 0.0);
    let mut g = gears();
    g[1].m_code = Some(41);
    assert_eq!(
        config(&c, g),
        Err(KrConfigError::GearMCode {
            first: 1,
            second: 2,
            m_code: 41
        })
    );
    let mut g = gears();
    g[0].output_range = 0x8000;
    assert!(matches!(
        config(&c, g),
        Err(KrConfigError::GearOutputRange { gear: 1, .. })
    ));
    let mut g = gears();
    g[1].max_rpm = 0.0;
    assert!(matches!(
        config(&c, g),
        Err(KrConfigError::GearMaxRpm { gear: 2, .. })
    ));
    assert_eq!(config(&c, vec![]), Err(KrConfigError::NoGears));
}

struct Run {
    kr: Kr,
    plc: PlcArea,
}

impl Run {
    fn new(kr: Kr) -> Self {
        Run {
            kr,
            plc: PlcArea::new(),
        }
    }

    fn tick(&mut self, program: ProgramSpindle, motion: Motion, x_mm: f64) -> KrOutput {
        self.tick_axis(program, motion, ControllingAxis::at(x_mm))
    }

    fn tick_axis(
        &mut self,
        program: ProgramSpindle,
        motion: Motion,
        axis: ControllingAxis,
    ) -> KrOutput {
        self.plc.begin_tick();
        self.kr.tick(
            &KrInput {
                program,
                motion,
                axis,
            },
            &mut self.plc,
        )
    }

    fn act(&self, c: CellId) -> i32 {
        self.plc.input(c)
    }
}

/// Spindle state of a block in gear M44, M3. `s_word` as the interpreter leaves it: the modal
/// S, or 0 after KŘR ended in a block without S.
fn block(css: bool, s_word: f64) -> ProgramSpindle {
    ProgramSpindle {
        dir: SpindleDir::Cw,
        css,
        s_word,
        limit_rpm: 0.0,
        gear: 2,
    }
}

fn close(a: f64, b: f64) -> bool {
    (a - b).abs() < 1e-9 * b.abs().max(1.0)
}

/// Lathe example (SPEC §6): `N10 G0 X300 Z100 M44 M3 S100` / `N15 Z-1` / `N20 G96 G1 F200 S90
/// X50` with R329 d3 = 3, or `N20 G97 ... S900` in the standard setting. Both give 90 m/min:
/// n = 90000 / (2π·150) = 95.4929658551 rpm at Ø300 and 90000 / (2π·25) = 572.957795131 rpm
/// at Ø50 (gear M44: P 2000 rpm).
fn lathe_example(r329: f64, s_word_n20: f64) {
    let mut r = Run::new(lathe(r329, 0.001));
    // N10: rapid to Ø300 at 100 rpm (no KŘR: S is rpm).
    let n10 = block(false, 100.0);
    for x in [400.0, 350.0, 300.0] {
        let o = r.tick(n10, Motion::Rapid, x);
        assert_eq!(o.speed_rpm, 100.0);
        assert!(!o.active);
    }
    // N15 Z-1: no new S, still 100 rpm.
    assert_eq!(
        r.tick(block(false, 100.0), Motion::Rapid, 300.0)
            .spindle_rpm,
        100.0
    );
    // N20: KŘR from Ø300 to Ø50.
    let n20 = block(true, s_word_n20);
    let o = r.tick(n20, Motion::Feed, 300.0);
    assert!(o.active);
    assert!(close(o.speed_rpm, 95.4929658551372), "{}", o.speed_rpm);
    assert_eq!(r.act(CellId::AkrrActV), 90_000);
    let o = r.tick(n20, Motion::Feed, 50.0);
    assert!(close(o.speed_rpm, 572.9577951308232), "{}", o.speed_rpm);
    assert_eq!(r.act(CellId::AkrrActS), 572_958);
    assert_eq!(r.act(CellId::AkrrActR), 25 * 8000);
}

#[test]
fn lathe_example_with_r329_swap_and_m_min() {
    lathe_example(0.3, 90.0);
}

#[test]
fn lathe_example_in_standard_setting() {
    lathe_example(0.0, 900.0);
}

/// Every ACT cell by hand: v = 90 m/min at Ø100 (r = 50 mm), gear M44 (P 2000, U 6000h = 24576),
/// G76 S2000. n = 90000/(2π·50) = 286.4788976 rpm; Ux = n/2000·24576 = 3520.25 → 3520.
#[test]
fn act_cells_hand_computed() {
    let mut r = Run::new(lathe(0.0, 0.001));
    let mut p = block(true, 900.0);
    p.limit_rpm = 2000.0;
    let o = r.tick(p, Motion::Feed, 100.0);
    assert_eq!(o.output, 3520);
    assert_eq!(r.act(CellId::AkrrActV), 90_000);
    assert_eq!(r.act(CellId::AkrrActSmax), 2_000_000);
    assert_eq!(r.act(CellId::AkrrActDist), 0);
    assert_eq!(r.act(CellId::AkrrActVcorr), 0);
    assert_eq!(r.act(CellId::AkrrActR), 400_000);
    assert_eq!(r.act(CellId::AkrrActP), 2_000_000);
    assert_eq!(r.act(CellId::AkrrActU), 24_576);
    assert_eq!(r.act(CellId::AkrrActS), 286_479);
    assert_eq!(r.act(CellId::AkrrActOut), 3520);

    // PLC radius correction +1 mm (8000 × 1/8 µm): r = 51 mm, n = 280.8616643 rpm, Ux = 3451.
    r.plc.write_by_name("AKRR_DIST", 8000).unwrap();
    r.plc
        .write_by_name("AKRR_CNTR", cntr::EXT_AKRR_DIST as i64)
        .unwrap();
    let o = r.tick(p, Motion::Feed, 100.0);
    assert_eq!(o.output, 3451);
    assert_eq!(r.act(CellId::AkrrActDist), 8000);
    assert_eq!(r.act(CellId::AkrrActR), 408_000);
    assert_eq!(r.act(CellId::AkrrActS), 280_862);

    // Plus a cutting speed correction of -9 m/min: v = 81000, n = 252.7754979 rpm, Ux = 3106.
    r.plc.write_by_name("AKRR_VCORR", -9000).unwrap();
    r.plc
        .write_by_name(
            "AKRR_CNTR",
            (cntr::EXT_AKRR_DIST | cntr::EXT_AKRR_VCORR) as i64,
        )
        .unwrap();
    let o = r.tick(p, Motion::Feed, 100.0);
    assert_eq!(o.output, 3106);
    assert_eq!(
        r.act(CellId::AkrrActV),
        90_000,
        "ACT_V is before the correction"
    );
    assert_eq!(r.act(CellId::AkrrActVcorr), -9000);
    assert_eq!(r.act(CellId::AkrrActS), 252_775);
}

/// Manual, version 2, example 1: `N100 G96 S500` acts at once, also in a block without motion.
/// S500 = 50 m/min; at Ø100: n = 50000/(2π·50) = 159.1549431 rpm.
#[test]
fn g96_in_a_block_without_motion_acts_at_once_in_version_2() {
    let mut r = Run::new(lathe(0.0, 0.001));
    r.tick(block(false, 100.0), Motion::Stationary, 100.0);
    let o = r.tick(block(true, 500.0), Motion::Stationary, 100.0);
    assert!(close(o.speed_rpm, 159.15494309189535));
    // `N200 S600` changes the cutting speed: 60 m/min → 190.9859317 rpm.
    let o = r.tick(block(true, 600.0), Motion::Stationary, 100.0);
    assert!(close(
        o.speed_rpm,
        60_000.0 / (std::f64::consts::TAU * 50.0)
    ));
}

/// Old KŘR (R580 = 00) computes in motion blocks only.
#[test]
fn old_kr_waits_for_a_motion_block() {
    let mut r = Run::new(lathe(0.0, 0.0));
    r.tick(block(false, 100.0), Motion::Stationary, 100.0);
    let o = r.tick(block(true, 500.0), Motion::Stationary, 100.0);
    assert!(o.active);
    assert_eq!(o.speed_rpm, 100.0, "old KŘR does not act outside motion");
    let o = r.tick(block(true, 500.0), Motion::Feed, 100.0);
    assert!(close(o.speed_rpm, 159.15494309189535));
}

/// Manual, version 2, example 2: `G76 S2000` limits KŘR to 2000 rpm. At Ø4 (r = 2 mm)
/// 50 m/min would need 3978.87 rpm; gear M44 allows 2000, G76 1500 → 1500.
#[test]
fn g76_limits_to_min_of_gear_and_limit() {
    let mut r = Run::new(lathe(0.0, 0.001));
    let mut p = block(true, 500.0);
    p.limit_rpm = 1500.0;
    assert_eq!(r.tick(p, Motion::Feed, 4.0).speed_rpm, 1500.0);
    assert_eq!(r.act(CellId::AkrrActSmax), 1_500_000);
    p.limit_rpm = 2500.0;
    assert_eq!(r.tick(p, Motion::Feed, 4.0).speed_rpm, 2000.0);
    assert_eq!(r.act(CellId::AkrrActOut), 0x6000);
    // Gear M41 (P 500) never changes gear, only clamps.
    p.gear = 1;
    assert_eq!(r.tick(p, Motion::Feed, 4.0).speed_rpm, 500.0);
    assert_eq!(r.act(CellId::AkrrActOut), 0x7FFF);
    // On the spindle axis the cap applies.
    assert_eq!(r.tick(p, Motion::Feed, 0.0).speed_rpm, 500.0);
}

/// R580 = 00 has no speed limit and no PLC control.
#[test]
fn old_kr_ignores_g76_and_the_plc() {
    let mut r = Run::new(lathe(0.0, 0.0));
    let mut p = block(true, 500.0);
    p.limit_rpm = 1500.0;
    assert_eq!(r.tick(p, Motion::Feed, 4.0).speed_rpm, 2000.0);
    r.plc.write_by_name("AKRR_V", 1000).unwrap();
    r.plc
        .write_by_name("AKRR_CNTR", cntr::EXT_AKRR_V as i64)
        .unwrap();
    let o = r.tick(p, Motion::Feed, 100.0);
    assert!(close(o.speed_rpm, 159.15494309189535));
}

/// SPEC §6: when KŘR ends and the next block has no S, the last reached speed becomes S.
/// Rapids follow the diameter while G96 is in force.
#[test]
fn last_reached_speed_becomes_s_and_rapids_follow_the_diameter() {
    let mut r = Run::new(lathe(0.0, 0.001));
    let g96 = block(true, 900.0);
    r.tick(g96, Motion::Feed, 50.0);
    // G0 back out under G96: speed follows Ø.
    let rapid = block(true, 900.0);
    let o = r.tick(rapid, Motion::Rapid, 100.0);
    assert!(close(o.speed_rpm, 286.4788975654116));
    let o = r.tick(rapid, Motion::Rapid, 200.0);
    assert!(close(o.speed_rpm, 143.2394487827058));
    // G94 without S (the interpreter leaves S = 0): KŘR ends, 143.24 rpm becomes S.
    let g94 = block(false, 0.0);
    for x in [200.0, 300.0, 10.0] {
        let o = r.tick(g94, Motion::Rapid, x);
        assert!(!o.active);
        assert!(close(o.speed_rpm, 143.2394487827058), "{}", o.speed_rpm);
    }
    // A later block without S keeps it; one with S1200 takes the new speed.
    assert!(close(
        r.tick(block(false, 0.0), Motion::Feed, 10.0).speed_rpm,
        143.2394487827058
    ));
    assert_eq!(
        r.tick(block(false, 1200.0), Motion::Feed, 10.0).speed_rpm,
        1200.0
    );
}

/// KŘR ended by a block that programs S itself: that S (rpm) applies at once.
#[test]
fn kr_ending_in_a_block_with_s_takes_that_s() {
    let mut r = Run::new(lathe(0.0, 0.001));
    r.tick(block(true, 900.0), Motion::Feed, 50.0);
    let o = r.tick(block(false, 800.0), Motion::Feed, 50.0);
    assert_eq!(o.speed_rpm, 800.0);
    assert_eq!(r.act(CellId::AkrrActV), 0);
}

/// Version 2: offsets and origin shifts act at once, also outside motion (tool tip); with
/// EXT_AKRR_SUPORT the carriage position is used.
#[test]
fn offsets_act_at_once_and_suport_uses_the_carriage() {
    let mut r = Run::new(lathe(0.0, 0.001));
    let p = block(true, 900.0);
    let carriage = |shift, offset| ControllingAxis {
        carriage_mm: 120.0,
        length_offset_mm: offset,
        origin_shift_mm: shift,
    };
    // Tip at 120 - 10 - 10 = Ø100 → 286.4789 rpm.
    let o = r.tick_axis(p, Motion::Stationary, carriage(10.0, 10.0));
    assert!(close(o.speed_rpm, 286.4788975654116));
    // New length offset 20 in a block without motion: tip at Ø90, at once.
    let o = r.tick_axis(p, Motion::Stationary, carriage(10.0, 20.0));
    assert!(close(
        o.speed_rpm,
        90_000.0 / (std::f64::consts::TAU * 45.0)
    ));
    assert_eq!(r.act(CellId::AkrrActR), 45 * 8000);
    // EXT_AKRR_SUPORT: Ø120 at the carriage.
    r.plc
        .write_by_name("AKRR_CNTR", cntr::EXT_AKRR_SUPORT as i64)
        .unwrap();
    let o = r.tick_axis(p, Motion::Stationary, carriage(10.0, 20.0));
    assert!(close(
        o.speed_rpm,
        90_000.0 / (std::f64::consts::TAU * 60.0)
    ));
    assert_eq!(r.act(CellId::AkrrActR), 60 * 8000);
}

/// Old KŘR: an offset change outside motion acts only with the next motion block.
#[test]
fn old_kr_applies_offset_changes_with_motion() {
    let mut r = Run::new(lathe(0.0, 0.0));
    let p = block(true, 900.0);
    let axis = |offset| ControllingAxis {
        carriage_mm: 100.0,
        length_offset_mm: offset,
        origin_shift_mm: 0.0,
    };
    let before = r.tick_axis(p, Motion::Feed, axis(0.0)).speed_rpm;
    let o = r.tick_axis(p, Motion::Stationary, axis(10.0));
    assert_eq!(o.speed_rpm, before);
    let o = r.tick_axis(p, Motion::Feed, axis(10.0));
    assert!(close(
        o.speed_rpm,
        90_000.0 / (std::f64::consts::TAU * 45.0)
    ));
}

/// PLC activation (EXT_AKRR_REQ) with the PLC cutting speed, while the program has no G96.
#[test]
fn plc_activates_kr() {
    let mut r = Run::new(lathe(0.0, 0.001));
    let p = block(false, 300.0);
    assert_eq!(r.tick(p, Motion::Stationary, 100.0).speed_rpm, 300.0);
    r.plc.write_by_name("AKRR_V", 60_000).unwrap();
    r.plc
        .write_by_name("AKRR_CNTR", (cntr::EXT_AKRR_REQ | cntr::EXT_AKRR_V) as i64)
        .unwrap();
    let o = r.tick(p, Motion::Stationary, 100.0);
    assert!(o.active);
    assert!(close(o.speed_rpm, 190.9859317102744));
    assert_eq!(r.act(CellId::AkrrActV), 60_000);
    // The PLC drops the request: KŘR ends, the program's S300 is in force again.
    r.plc.write_by_name("AKRR_CNTR", 0).unwrap();
    let o = r.tick(p, Motion::Stationary, 100.0);
    assert!(!o.active);
    assert_eq!(o.speed_rpm, 300.0);
    // Had the program no S (S = 0 after a G96 ended), the last reached speed would stay.
    r.plc
        .write_by_name("AKRR_CNTR", (cntr::EXT_AKRR_REQ | cntr::EXT_AKRR_V) as i64)
        .unwrap();
    r.tick(block(false, 0.0), Motion::Stationary, 100.0);
    r.plc.write_by_name("AKRR_CNTR", 0).unwrap();
    let o = r.tick(block(false, 0.0), Motion::Stationary, 100.0);
    assert!(close(o.speed_rpm, 190.9859317102744));
}

#[test]
fn direction_and_faults() {
    let mut r = Run::new(lathe(0.0, 0.001));
    let mut p = block(false, 300.0);
    p.dir = SpindleDir::Ccw;
    assert_eq!(r.tick(p, Motion::Feed, 100.0).spindle_rpm, -300.0);
    p.dir = SpindleDir::Stopped;
    let o = r.tick(p, Motion::Feed, 100.0);
    assert_eq!((o.spindle_rpm, o.speed_rpm), (0.0, 300.0));
    // Plain S is clamped to the gear maximum too.
    p.dir = SpindleDir::Cw;
    p.s_word = 5000.0;
    assert_eq!(r.tick(p, Motion::Feed, 100.0).spindle_rpm, 2000.0);
    p.gear = 7;
    let o = r.tick(p, Motion::Feed, 100.0);
    assert_eq!(o.fault, Some(KrFault::UnknownGear(7)));
    assert_eq!((o.spindle_rpm, o.output), (0.0, 0));
    assert_eq!(r.act(CellId::AkrrActS), 0);
    p.gear = 2;
    let o = r.tick(p, Motion::Feed, f64::NAN);
    assert_eq!(o.fault, Some(KrFault::BadPosition));
    assert_eq!(
        o.spindle_rpm, 0.0,
        "speed after the gear fault was 0 and stays"
    );
}

/// Spindle override (issue #19): scales the commanded speed, 50..120 %, never above the gear
/// range's P; the program's speed is kept, so 100 % gives it back exactly.
#[test]
fn spindle_override_scales_within_the_gear_range() {
    let mut r = Run::new(lathe(0.001, 0.001));
    let s = block(false, 1000.0);
    assert_eq!(r.tick(s, Motion::Feed, 100.0).spindle_rpm, 1000.0);
    r.kr.set_override(50.0);
    let o = r.tick(s, Motion::Feed, 100.0);
    assert_eq!((o.spindle_rpm, o.speed_rpm), (500.0, 500.0));
    assert_eq!(r.act(CellId::AkrrActS), 500_000);
    r.kr.set_override(20.0); // below the range: 50 %
    assert_eq!(r.tick(s, Motion::Feed, 100.0).spindle_rpm, 500.0);
    r.kr.set_override(120.0);
    assert_eq!(r.tick(s, Motion::Feed, 100.0).spindle_rpm, 1200.0);
    // S1900 at 120 % would be 2280 rpm: gear M44 stops at P = 2000 rpm.
    assert_eq!(
        r.tick(block(false, 1900.0), Motion::Feed, 100.0)
            .spindle_rpm,
        2000.0
    );
    r.kr.set_override(100.0);
    assert_eq!(r.tick(s, Motion::Feed, 100.0).spindle_rpm, 1000.0);
}
