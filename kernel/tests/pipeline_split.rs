//! The validation pass split in two halves (`kernel::pipeline::split`, for two threads) is the
//! serial pass, to the message and to every block and segment its observer sees: on every
//! program of the corpora, in both dialects.

use std::path::Path;

use kernel::block::Block;
use kernel::comp::{CompBlock, CompConfig};
use kernel::constants::Constants;
use kernel::machine::MachineSetup;
use kernel::pipeline::split::{Checking, Interpreting, run_here};
use kernel::pipeline::{Flow, Observer, Options, Validation, validate_lines_into};
use kernel::plan::{PlannerConfig, Segment};
use kernel::program::{Dialect, Modal, Setup, StrLines};

/// Everything an observer is given, in order.
#[derive(Default)]
struct Seen(Vec<String>);

impl Observer for Seen {
    fn programmed(&mut self, b: &Block, modal: &Modal) {
        self.0.push(format!("{b:?} {modal:?}"));
    }
    fn compensated(&mut self, c: &CompBlock) {
        self.0.push(format!("{c:?}"));
    }
    fn segment(&mut self, s: &Segment) -> Flow {
        self.0.push(format!("{s:?}"));
        Flow::Go
    }
}

fn setup(dialect: Dialect) -> MachineSetup {
    let mut s = Setup::new(&['X', 'Y', 'Z']);
    s.dialect = dialect;
    let c = Constants::new();
    MachineSetup::from_stages(
        s,
        CompConfig::from_constants(&c),
        PlannerConfig::uniform(3, 200.0, 800.0),
    )
}

/// The split pass with batches of `batch` outputs, as the daemon hands them over.
fn split(text: &str, s: &MachineSetup, batch: usize) -> (Validation, Seen) {
    let mut seen = Seen::default();
    let opts = Options::default();
    let Ok(front) = Interpreting::new(StrLines::new(text), s, opts) else {
        panic!("not a restart");
    };
    let back = Checking::new(s, opts, &mut seen);
    let v = run_here(front, back, batch);
    (v, seen)
}

fn programs(dir: &Path, ext: &str, into: &mut Vec<std::path::PathBuf>) {
    for e in std::fs::read_dir(dir).unwrap() {
        let p = e.unwrap().path();
        if p.is_dir() {
            programs(&p, ext, into);
        } else if p.extension().is_some_and(|x| x == ext) {
            into.push(p);
        }
    }
}

#[test]
fn the_split_pass_is_the_serial_pass_on_every_corpus_program() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests");
    let mut checked = 0;
    for (dir, ext, dialect) in [
        ("corpus", "nc", Dialect::Cnc836),
        ("data/cnc836", "nc", Dialect::Cnc836),
        ("data/rs274", "ngc", Dialect::Iso),
    ] {
        let mut files = Vec::new();
        programs(&root.join(dir), ext, &mut files);
        files.sort();
        let s = setup(dialect);
        for f in files {
            let bytes = std::fs::read(&f).unwrap();
            let text = String::from_utf8_lossy(&bytes);
            let mut seen = Seen::default();
            let serial =
                validate_lines_into(StrLines::new(&text), &s, Options::default(), &mut seen);
            for batch in [1, 64] {
                let (v, split_seen) = split(&text, &s, batch);
                assert_eq!(v, serial, "{}", f.display());
                assert!(
                    split_seen.0 == seen.0,
                    "{}: what the observer saw",
                    f.display()
                );
            }
            checked += 1;
        }
    }
    assert!(checked > 100, "{checked} programs");
}
