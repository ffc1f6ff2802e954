//! Serial link (in progress).
