//! Fuzz target: radius compensation (`kernel::comp::fuzz::fuzz_entry`): random open and closed
//! contours of lines and arcs, both sides, every R339 mode; never panics, never outputs a
//! non-finite position, and every gouge is named by a message. The same entry runs in the
//! proptest `kernel/tests/comp_fuzz.rs` on stable.
#![no_main]

libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    kernel::comp::fuzz::fuzz_entry(data);
});
