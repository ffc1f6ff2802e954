//! Fuzz target: the MTConnect agent's request door (`daemon::mtconnect::fuzz::fuzz_entry`:
//! path, query and XPath never panic; a selection names the model's items only).
#![no_main]

libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    daemon::mtconnect::fuzz::fuzz_entry(data);
});
