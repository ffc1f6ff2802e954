//! Fuzz target: the configuration file (`daemon::runtime::config::Config::fuzz_entry`: the
//! parse and validation `--check-config` runs never panic; errors carry a code).
#![no_main]

libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    daemon::runtime::config::Config::fuzz_entry(data);
});
