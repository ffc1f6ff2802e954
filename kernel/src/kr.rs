//! Constant cutting speed KŘR, G96/G97/G76 (SPEC §6). Issue #7.
