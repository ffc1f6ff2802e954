//! KŘR invariants over arbitrary inputs (SPEC §6): never panics, speed within min(P, limit),
//! output within 0..U, and the ACT cells agree with the output.

use kernel::block::SpindleDir;
use kernel::constants::Constants;
use kernel::kr::{
    ControllingAxis, Gear, Kr, KrConfig, KrFault, KrInput, Motion, ProgramSpindle, RadiusInput,
};
use kernel::plc::{CellId, PlcArea, PlcWrite};
use proptest::prelude::*;

fn kr(v2: bool) -> Kr {
    let mut c = Constants::new();
    c.set(0, 1.0);
    c.set(1, 3.0);
    c.set(2, 0.0);
    c.set(67, 1.0);
    c.set(580, if v2 { 0.001 } else { 0.0 });
    let gears = vec![
        Gear {
            max_rpm: 800.0,
            output_range: 0x7FFF,
            m_code: Some(41),
        },
        Gear {
            max_rpm: 3000.0,
            output_range: 0x5000,
            m_code: Some(42),
        },
    ];
    Kr::new(KrConfig::from_constants(&c, RadiusInput::Diameter, gears).unwrap())
}

fn dir() -> impl Strategy<Value = SpindleDir> {
    prop_oneof![
        Just(SpindleDir::Cw),
        Just(SpindleDir::Ccw),
        Just(SpindleDir::Stopped)
    ]
}

fn motion() -> impl Strategy<Value = Motion> {
    prop_oneof![
        Just(Motion::Stationary),
        Just(Motion::Rapid),
        Just(Motion::Feed)
    ]
}

prop_compose! {
    fn step()(
        dir in dir(),
        css in any::<bool>(),
        s_word in 0.0f64..5000.0,
        limit_rpm in prop_oneof![Just(0.0), 1.0f64..5000.0],
        gear in 0u8..4,
        motion in motion(),
        carriage_mm in -1000.0f64..1000.0,
        length_offset_mm in -50.0f64..50.0,
        origin_shift_mm in -50.0f64..50.0,
        cntr in 0i64..64,
        plc_v in 0i64..9_999_900,
        plc_smax in 0i64..99_999_000,
        plc_dist in -8_000_000i64..8_000_000,
        plc_vcorr in -9_999_900i64..9_999_900,
    ) -> (KrInput, [PlcWrite; 5]) {
        let input = KrInput {
            program: ProgramSpindle { dir, css, s_word, limit_rpm, gear },
            motion,
            axis: ControllingAxis { carriage_mm, length_offset_mm, origin_shift_mm },
        };
        let w = |n, v| PlcWrite::by_name(n, v).unwrap();
        (input, [
            w("AKRR_CNTR", cntr),
            w("AKRR_V", plc_v),
            w("AKRR_SMAX", plc_smax),
            w("AKRR_DIST", plc_dist),
            w("AKRR_VCORR", plc_vcorr),
        ])
    }
}

proptest! {
    #[test]
    fn outputs_stay_in_range(v2 in any::<bool>(), steps in prop::collection::vec(step(), 1..40)) {
        let mut kr = kr(v2);
        let mut plc = PlcArea::new();
        for (input, writes) in steps {
            for w in writes {
                plc.stage(w);
            }
            plc.begin_tick();
            let out = kr.tick(&input, &mut plc);
            let p = input.program;
            if p.gear == 3 {
                prop_assert_eq!(out.fault, Some(KrFault::UnknownGear(3)));
                prop_assert_eq!((out.spindle_rpm, out.output), (0.0, 0));
                continue;
            }
            prop_assert_eq!(out.fault, None);
            let (max_rpm, u) = if p.gear == 2 { (3000.0, 0x5000) } else { (800.0, 0x7FFF) };
            prop_assert!((0.0..=max_rpm).contains(&out.speed_rpm), "{}", out.speed_rpm);
            prop_assert!(out.output <= u);
            let smax = plc.input(CellId::AkrrActSmax);
            if out.active && smax > 0 {
                // The cell holds the limit rounded to 1/1000 rpm.
                prop_assert!(out.speed_rpm <= f64::from(smax) / 1000.0 + 0.0005);
            }
            prop_assert_eq!(plc.input(CellId::AkrrActOut), i32::from(out.output));
            prop_assert_eq!(
                plc.input(CellId::AkrrActS),
                (out.speed_rpm * 1000.0).round() as i32
            );
            let expect_rpm = match p.dir {
                SpindleDir::Cw => out.speed_rpm,
                SpindleDir::Ccw => -out.speed_rpm,
                SpindleDir::Stopped => 0.0,
            };
            prop_assert_eq!(out.spindle_rpm, expect_rpm);
        }
    }
}
