//! Everything around the kernel that touches clocks, threads, sockets and files.
pub mod api;
pub mod buses;
pub mod clock;
pub mod config;
pub mod controller;
pub mod fault_inject;
pub mod harness;
pub mod job;
pub mod library;
pub mod logging;
pub mod pipeline;
pub mod rt;
pub mod rt_core;
pub mod server;
pub mod stats;
pub mod storage;
pub mod systemd;
