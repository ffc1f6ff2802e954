//! Property tests: generate → write → parse round-trips for TAB0.KOR, the constants file and
//! programs, and the fuzz entry points on arbitrary input (the same functions the cargo-fuzz
//! targets in `fuzz/` call, so they are type-checked and exercised on stable).

use kernel::block::Feed;
use kernel::constants::Constants;
use kernel::offsets::{self, KorFile, OffsetEntry, OffsetTable};
use kernel::program::{Setup, compile};
use proptest::prelude::*;

fn axes() -> impl Strategy<Value = Vec<char>> {
    prop_oneof![
        Just(vec!['X', 'Y', 'Z']),
        Just(vec!['X', 'Y', 'Z', 'U']),
        Just(vec!['X', 'Z']),
        Just(vec!['X', 'Y', 'Z', 'A', 'B']),
    ]
}

/// Values as an operator writes them: up to 5 integer digits and up to 6 decimals.
fn value() -> impl Strategy<Value = f64> {
    (-99_999_999_999i64..=99_999_999_999, 0u32..=6).prop_map(|(m, d)| {
        let scale = 10i64.pow(6 - d);
        let m = m / scale * scale;
        format!("{}.{:06}", m / 1_000_000, (m % 1_000_000).abs())
            .replace("0.", if m < 0 && m > -1_000_000 { "-0." } else { "0." })
            .parse::<f64>()
            .unwrap()
    })
}

fn table() -> impl Strategy<Value = OffsetTable> {
    proptest::collection::vec(
        (1u8..=99, value(), [value(), value(), value(), value()]),
        0..40,
    )
    .prop_map(|entries| {
        let mut t = OffsetTable::new();
        for (n, r, l) in entries {
            t.set_entry(
                n,
                OffsetEntry {
                    radius_mm: r,
                    length_mm: l,
                },
            )
            .unwrap();
        }
        t
    })
}

proptest! {
    #[test]
    fn kor_file_round_trips(t in table(), axes in axes(), comment in "([a-zA-Z0-9 .,:=]{0,30}\n){0,3}") {
        let f = KorFile { comment, table: t };
        let text = offsets::write(&f, &axes);
        let back = offsets::parse(&text, &axes).unwrap();
        prop_assert_eq!(back, f);
    }

    #[test]
    fn operator_edit_lines_round_trip(n in 1u8..=99, vals in proptest::array::uniform5(proptest::option::of(value()))) {
        let axes = ['X', 'Y', 'Z', 'U'];
        let mut line = format!("{n:02}:");
        for (k, v) in vals.iter().enumerate() {
            if let Some(v) = v {
                let key = if k == 0 { "R".to_string() } else { offsets::label(k, &axes) };
                line.push_str(&format!(" {key}={v}"));
            }
        }
        let e = offsets::parse_edit(&line, &axes).unwrap();
        prop_assert_eq!(e.entry, n);
        prop_assert_eq!(e.values, vals);
    }

    #[test]
    fn constants_file_round_trips(set in proptest::collection::btree_map(0u16..=999, -99_999_999i64..=99_999_999, 0..60)) {
        let mut c = Constants::new();
        for (&r, &m) in &set {
            c.set(r, m as f64 / 1000.0);
        }
        for (&r, &m) in &set {
            prop_assert_eq!(c.milli(r), m);
        }
        let back = Constants::parse(&c.to_text()).unwrap();
        prop_assert_eq!(back, c);
    }

    /// Generated linear programs: every written number reaches the block exactly, F follows
    /// its decimal point (SPEC §5).
    #[test]
    fn program_numbers_round_trip(moves in proptest::collection::vec(
        (proptest::array::uniform3(-99_999_999i64..=99_999_999), any::<bool>(), 1u32..=95_000, any::<bool>()), 1..30)) {
        let mut text = String::new();
        for (k, (xyz, rapid, f, point)) in moves.iter().enumerate() {
            let fmt = |m: i64| format!("{}{}.{:03}", if m < 0 { "-" } else { "" }, m.abs() / 1000, m.abs() % 1000);
            let fword = if *point { format!("{}.{:03}", f / 1000, f % 1000) } else { f.to_string() };
            text.push_str(&format!(
                "N{k} {} X{} Y{} Z{} F{fword}\n",
                if *rapid { "G0" } else { "G1" },
                fmt(xyz[0]), fmt(xyz[1]), fmt(xyz[2])
            ));
        }
        let c = compile(&text, &Setup::new(&['X', 'Y', 'Z']));
        // F1.234 (point, m/min) and F1234 (mm/min) are the same feed; above 90000 mm/min refused.
        let too_fast = moves.iter().any(|m| m.2 > 90_000);
        prop_assert_eq!(c.has_errors(), too_fast, "{:?}", c.diagnostics);
        if !too_fast {
            for (b, (xyz, _, f, point)) in c.blocks.iter().zip(&moves) {
                let (_, end, _) = b.motion().unwrap();
                for k in 0..3 {
                    prop_assert_eq!(end[k], xyz[k] as f64 / 1000.0);
                }
                let _ = point;
                prop_assert_eq!(b.feed, Feed::MmPerMin(*f as f64));
            }
        }
    }
}

proptest! {
    /// Generated arcs written to 4 decimals pass the R55 check and keep their centre and
    /// direction; moved 0.1 mm off the circle they are refused.
    #[test]
    fn program_arcs_round_trip(
        c in proptest::array::uniform2(-500.0f64..500.0),
        r in 0.5f64..300.0,
        a0 in 0.0f64..std::f64::consts::TAU,
        sweep in 0.1f64..6.0,
        cw in any::<bool>(),
    ) {
        let a1 = if cw { a0 - sweep } else { a0 + sweep };
        let p = |a: f64| (c[0] + r * a.cos(), c[1] + r * a.sin());
        let f4 = |v: f64| format!("{v:.4}");
        let (s, e) = (p(a0), p(a1));
        let (sx, sy) = (f4(s.0).parse::<f64>().unwrap(), f4(s.1).parse::<f64>().unwrap());
        let text = format!(
            "G0 X{} Y{}\n{} X{} Y{} I{} J{} F100\n",
            f4(sx), f4(sy), if cw { "G2" } else { "G3" }, f4(e.0), f4(e.1),
            f4(c[0] - sx), f4(c[1] - sy)
        );
        let setup = Setup::new(&['X', 'Y', 'Z']);
        let out = compile(&text, &setup);
        prop_assert!(!out.has_errors(), "{text}: {:?}", out.diagnostics);
        let Some((_, _, kernel::block::Path::Arc { dir, center, .. })) = out.blocks[1].motion() else {
            panic!("not an arc");
        };
        prop_assert_eq!(dir == kernel::block::ArcDir::Cw, cw);
        let ci: f64 = f4(c[0] - sx).parse().unwrap();
        let cj: f64 = f4(c[1] - sy).parse().unwrap();
        prop_assert!((center[0] - (sx + ci)).abs() < 1e-9 && (center[1] - (sy + cj)).abs() < 1e-9);
        // Same arc with the end point pushed 0.1 mm outwards: beyond R55 = 0.01 mm.
        let e_out = (c[0] + (r + 0.1) * a1.cos(), c[1] + (r + 0.1) * a1.sin());
        let bad = text.replace(&format!("X{} Y{} I", f4(e.0), f4(e.1)), &format!("X{} Y{} I", f4(e_out.0), f4(e_out.1)));
        prop_assert!(compile(&bad, &setup).has_errors(), "{bad}");
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(2000))]

    /// The fuzz targets' entry points on NC-like token soup (reaches deep into the interpreter).
    #[test]
    fn fuzz_entries_on_token_soup(s in "([NGXYZUIJEFSMDR&=;.“ 0-9\\-+\"]|G[0-9]{1,2}|R[0-9]=|\n){0,120}") {
        kernel::program::fuzz_entry(s.as_bytes());
        kernel::offsets::fuzz_entry(format!("$KOR\n{s}").as_bytes());
        kernel::constants::fuzz_entry(s.as_bytes());
    }

    /// ... on ISO-like token soup: expressions, parameters, O-words, cycles.
    #[test]
    fn fuzz_entries_on_iso_token_soup(
        s in r"(G0|G1|G2|G3|G4|G81|G83|G73|G91|G90|G20|G43|G41|G92|G10 L2 P1|X1|Y-2|Z\.5|R2|R-1|Q\.5|P1|L2|I1|J-1|F100|H1|D1|T1|M6|M3|M30|#1=|#<a>=|#1|#<a>|\[|\]|\+|\*|/|SIN|ATAN|EQ|o1 |o2 |sub|endsub|call|while|endwhile|if|else|endif|repeat|endrepeat|do|break|continue|\(|\)|;| |\n){0,80}"
    ) {
        kernel::program::fuzz_entry(s.as_bytes());
    }

    /// ... and on arbitrary bytes.
    #[test]
    fn fuzz_entries_on_bytes(b in proptest::collection::vec(any::<u8>(), 0..300)) {
        kernel::program::fuzz_entry(&b);
        kernel::offsets::fuzz_entry(&b);
        kernel::constants::fuzz_entry(&b);
    }
}

#[test]
fn fuzz_entries_on_seeds() {
    // Valid inputs make the round-trip assertions inside the entries run.
    kernel::offsets::fuzz_entry(b"x\n$KOR\n01: R=10.0 X=20.0 Y=30.0 Z=40.0\n95: 1=12.55\n");
    kernel::constants::fuzz_entry(b"R339=-21140.000\nR397=01011.111\n");
    kernel::program::fuzz_entry(b"N10 D1 G41 G1 X10 F100\nN20 G2 X20 Y0 I5 J0\nN30 G40 G1 X30\n");
}
