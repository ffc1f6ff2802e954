; SETUP lathe
; CONST R329=00000.300
; kernel/tests/lang_program.rs: the manual's lathe example with the G96/G97 swap (R329 d3 = 3).
N10 G0 X300 Z100 M44 M3 S100 “rapid to diameter 300
N15 Z-1
N20 G96 G1 F200 S90 X50
N30 G18
