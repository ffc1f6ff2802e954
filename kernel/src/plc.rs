//! PLC register area with the AKRR_* cells and DYNAM_SET (SPEC §6, §7.4). Issue #7.
