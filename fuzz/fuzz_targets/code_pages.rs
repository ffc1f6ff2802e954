//! Fuzz target: the legacy code pages of stored programs
//! (`kernel::program::encoding::fuzz_entry`: one character per byte, UTF-8 only when valid).
#![no_main]

libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    kernel::program::encoding::fuzz_entry(data);
});
