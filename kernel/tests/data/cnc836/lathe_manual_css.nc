; The manual's lathe example (seed 002, SPEC §6), R329 d3 = 3: facing from Ø300 to Ø50 at a
; constant cutting speed of 90 m/min with 0.2 mm/rev (F without a point: µm/rev).
N10 G0 X300 Z100 M44 M3 S100 "rapid to diameter 300
N15 Z-1
N20 G96 G1 F200 S90 X50
N30 G94 G0 X300 Z100 S100
N40 M5
