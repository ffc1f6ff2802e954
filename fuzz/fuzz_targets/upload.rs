//! Fuzz target: the unary upload sessions (`daemon::runtime::api::upload_fuzz::fuzz_entry`:
//! begin, part, finish and idle sweeps against a model; a stored program is the bytes sent).
#![no_main]

libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    daemon::runtime::api::upload_fuzz::fuzz_entry(data);
});
