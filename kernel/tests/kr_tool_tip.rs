//! KŘR at the tool tip (SPEC §6, version 2): the interpreter hands the length offset in force
//! for the controlling axis R67 to the RT side with the spindle state, `ControllingAxis::of`
//! turns the carriage position and that offset into the tip, and EXT_AKRR_SUPORT computes at
//! the carriage instead.

use std::f64::consts::PI;

use kernel::block::{Block, BlockKind};
use kernel::constants::Constants;
use kernel::kr::{
    ControllingAxis, Gear, Kr, KrConfig, KrInput, Motion, ProgramSpindle, RadiusInput,
};
use kernel::offsets::{OffsetEntry, OffsetTable};
use kernel::plc::{CellId, PlcArea, cntr};
use kernel::program::{Setup, compile};

fn constants() -> Constants {
    let mut c = Constants::new();
    c.set(0, 1.0); // R0: X
    c.set(1, 3.0); // R1: Z
    c.set(2, 0.0);
    c.set(67, 1.0); // X controls KŘR
    c.set(580, 0.001); // version 2
    c
}

fn kr() -> Kr {
    let gears = vec![Gear {
        max_rpm: 3000.0,
        output_range: 0x7FFF,
        m_code: Some(41),
    }];
    Kr::new(KrConfig::from_constants(&constants(), RadiusInput::Diameter, gears).unwrap())
}

/// A lathe X (diameter) Z whose offset entry 1 has X length 20 (diameter units) and Z 5.
fn compile_lathe(text: &str) -> Vec<Block> {
    let mut table = OffsetTable::new();
    table
        .set_entry(
            1,
            OffsetEntry {
                radius_mm: 0.4,
                length_mm: [20.0, 5.0, 0.0, 0.0],
            },
        )
        .unwrap();
    let mut setup = Setup::from_machine(constants(), table);
    setup.start[0] = 300.0;
    setup.start[1] = 100.0;
    let c = compile(text, &setup);
    assert!(!c.has_errors(), "{:?}", c.diagnostics);
    c.blocks
}

/// Speed KŘR computes for a carriage at `carriage_mm` with the spindle state of `block`.
fn speed_rpm(block: &Block, carriage_mm: f64, cntr_bits: u32) -> f64 {
    let mut kr = kr();
    let mut plc = PlcArea::new();
    plc.write_by_name("AKRR_CNTR", i64::from(cntr_bits))
        .unwrap();
    plc.begin_tick();
    let out = kr.tick(
        &KrInput {
            program: ProgramSpindle::from_block(block),
            motion: Motion::Feed,
            axis: ControllingAxis::of(carriage_mm, &block.spindle),
        },
        &mut plc,
    );
    assert_eq!(out.fault, None);
    // AKRR_ACT_R shows the radius the speed came from, in 1/8 µm.
    let r_mm = f64::from(plc.input(CellId::AkrrActR)) / 8000.0;
    assert!((out.speed_rpm - 90_000.0 / (2.0 * PI * r_mm)).abs() < 1e-3 * out.speed_rpm);
    out.speed_rpm
}

fn motion_end_x(b: &Block) -> f64 {
    match b.kind {
        BlockKind::Motion { end, .. } => end[0],
        _ => panic!("not a motion block: {b:?}"),
    }
}

#[test]
fn the_length_offset_of_the_controlling_axis_rides_with_the_spindle_state() {
    let blocks = compile_lathe(
        "N10 G0 X100 Z1 M3 S500\n\
         N20 G96 G1 X50 F2000 S900\n\
         N30 &1\n\
         N40 G1 X40\n\
         N50 G92 D1 R1=30\n\
         N60 G1 X30\n\
         N70 &0\n\
         N80 G1 X30\n",
    );
    let off: Vec<(Option<u32>, f64)> = blocks
        .iter()
        .map(|b| (b.n, b.spindle.length_offset_mm))
        .collect();
    assert_eq!(
        off,
        [
            (Some(10), 0.0),
            (Some(20), 0.0),
            // `&1` acts at once, in the block that selects it (no motion yet).
            (Some(30), 20.0),
            (Some(40), 20.0),
            // A G92 write of the entry in force changes it from that block on.
            (Some(50), 30.0),
            (Some(60), 30.0),
            (Some(70), 0.0),
            (Some(80), 0.0),
        ]
    );
    assert!(blocks.iter().all(|b| b.spindle.origin_shift_mm == 0.0));
    // The carriage goes to program X + offset; the tip is at the programmed X.
    assert_eq!(motion_end_x(&blocks[3]), 60.0);
    assert_eq!(motion_end_x(&blocks[5]), 60.0);
}

#[test]
fn g96_speed_follows_the_tip_radius_and_ext_akrr_suport_the_carriage() {
    let with = compile_lathe("N10 G0 X100 Z1 M3 &1\nN20 G96 G1 X40 F2000 S900\n");
    let without = compile_lathe("N10 G0 X100 Z1 M3\nN20 G96 G1 X40 F2000 S900\n");
    let (w, wo) = (&with[1], &without[1]);
    let (w_carriage, wo_carriage) = (motion_end_x(w), motion_end_x(wo));
    assert_eq!((w_carriage, wo_carriage), (60.0, 40.0));

    // Same tip (Ø40) in both runs, so the same speed: v / (π·40), although the carriages
    // stand at Ø60 and Ø40.
    let tip = 90_000.0 / (PI * 40.0);
    let a = speed_rpm(w, w_carriage, 0);
    let b = speed_rpm(wo, wo_carriage, 0);
    assert!((a - tip).abs() < 1e-6 * tip, "{a} vs {tip}");
    assert!((b - tip).abs() < 1e-6 * tip, "{b} vs {tip}");

    // EXT_AKRR_SUPORT: the carriage diameter (Ø60) counts, without offsets.
    let c = speed_rpm(w, w_carriage, cntr::EXT_AKRR_SUPORT);
    let carriage = 90_000.0 / (PI * 60.0);
    assert!((c - carriage).abs() < 1e-6 * carriage, "{c} vs {carriage}");
    // Without an offset the bit changes nothing.
    let d = speed_rpm(wo, wo_carriage, cntr::EXT_AKRR_SUPORT);
    assert!((d - tip).abs() < 1e-6 * tip);

    // An origin shift counts like the length offset: tip = carriage − shift − offset.
    let mut shifted = *w;
    shifted.spindle.origin_shift_mm = 10.0;
    let e = speed_rpm(&shifted, w_carriage, 0);
    let tip30 = 90_000.0 / (PI * 30.0);
    assert!((e - tip30).abs() < 1e-6 * tip30, "{e} vs {tip30}");
}
