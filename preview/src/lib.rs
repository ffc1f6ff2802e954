//! Program preview and continuity diagnostics as pictures (SPEC §7.5). Issue #10.
