//! Everything around the kernel that touches clocks, threads, sockets and files.
pub mod storage;
