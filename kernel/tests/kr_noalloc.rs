//! The KŘR tick and the PLC area's controller side run on the RT thread: they must not allocate
//! (ARCHITECTURE.md, threads). Counted per thread by the
//! shared counting allocator, so other threads of the test harness do not count.

#[global_allocator]
static ALLOC: alloc_count::Counting = alloc_count::Counting;

use kernel::block::SpindleDir;
use kernel::constants::Constants;
use kernel::kr::{
    ControllingAxis, Gear, Kr, KrConfig, KrInput, Motion, ProgramSpindle, RadiusInput,
};
use kernel::plc::{PlcArea, PlcWrite, cntr};

#[test]
fn tick_does_not_allocate() {
    let mut c = Constants::new();
    c.set(67, 1.0);
    c.set(580, 0.001);
    let gears = vec![Gear {
        max_rpm: 1000.0,
        output_range: 0x7FFF,
        m_code: None,
    }];
    let mut kr = Kr::new(KrConfig::from_constants(&c, RadiusInput::Diameter, gears).unwrap());
    let mut plc = PlcArea::new();
    let writes = [
        PlcWrite::by_name("AKRR_V", 80_000).unwrap(),
        PlcWrite::by_name("AKRR_CNTR", i64::from(cntr::ALL)).unwrap(),
    ];
    let before = alloc_count::allocations();
    let mut sum = 0.0;
    for k in 0..10_000 {
        if k == 5000 {
            for w in writes {
                plc.stage(w);
            }
        }
        plc.begin_tick();
        let out = kr.tick(
            &KrInput {
                program: ProgramSpindle {
                    dir: SpindleDir::Cw,
                    css: true,
                    s_word: 900.0,
                    limit_rpm: 800.0,
                    gear: 1,
                },
                motion: Motion::Feed,
                axis: ControllingAxis::at(300.0 - k as f64 * 0.025),
            },
            &mut plc,
        );
        sum += out.spindle_rpm;
    }
    assert_eq!(alloc_count::allocations(), before);
    assert!(sum > 0.0);
}
