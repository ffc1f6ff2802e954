//! Everything around the kernel that touches clocks, threads, sockets and files.
pub mod buses;
pub mod config;
pub mod storage;
