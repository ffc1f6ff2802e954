//! Offset table TAB0.KOR (SPEC §3). Issue #3.
