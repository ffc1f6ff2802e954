; kernel/tests/lang_program.rs: G76 limit, leaving KŘR without S, spindle M groups.
S500 M3
N100 G76 S2000
M3 G96 S500
G95 G1 X10 F100
M4 S800 M41
G97 X20 F200 S300
G94 G1 X0 F500 M5 M8
M3 M4
