; Turning with feed per revolution (G95): a cylinder Ø80 and a taper to Ø100, with the
; spindle limited by gear 3 (P = 1000 rpm): S1200 runs at 1000 rpm, F0.25 = 250 mm/min.
N10 G0 X80 Z102 M43 M3 S1200
N20 G95 G1 Z60 F0.25
N30 X100 Z40
N40 G94 G0 X300 Z100
N50 M5
