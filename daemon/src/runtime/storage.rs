//! Durable file storage for TAB0.KOR and the constants file (atomic replace). Issue #3.
