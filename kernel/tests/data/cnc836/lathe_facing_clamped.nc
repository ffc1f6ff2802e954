; Facing under G96 with a spindle limit (G76): 120 m/min down to Ø20, never above 1500 rpm.
N10 G0 X200 Z100 M44 M3 S200
N15 G76 S1500
N20 Z0
N30 G96 G1 F150 S120 X20
N40 G94 G0 X200 Z100 S200
N50 M5
