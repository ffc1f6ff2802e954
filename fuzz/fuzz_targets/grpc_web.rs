//! Fuzz target: the HMI port's grpc-web door (`daemon::runtime::hmi::fuzz::fuzz_entry`: a
//! request in binary or text framing to the HMI's routed services never panics, is answered
//! within a bounded time, and a gRPC answer carries a grpc-status).
#![no_main]

libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    daemon::runtime::hmi::fuzz::fuzz_entry(data);
});
