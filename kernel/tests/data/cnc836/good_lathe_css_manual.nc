; SETUP lathe
; CONST R329=00000.300
; Seed 002 §6.1 lathe example (R329 decade 3 = 3: G96 = feed per revolution, S in m/min)
N10 G0 X300 Z100 M44 M3 S100 “rapid to diameter 300, 100 rpm
N15 Z-1
N20 G96 G1 F200 S90 X50 “CSS 90 m/min, down to diameter 50, F = 0.2 mm/rev
N25 G76 S2000 „limit 2000 rpm
N30 G94 G0 X300 M5
