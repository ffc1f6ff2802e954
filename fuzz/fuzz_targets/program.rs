//! Fuzz target: the program parser (`kernel::program::fuzz_entry`: never panics, round-trips what it
//! accepts). The same entry runs in the proptest `kernel/tests/lang_props.rs` on stable.
#![no_main]

libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    kernel::program::fuzz_entry(data);
});
