; Dwell G4 F<seconds> (docs/language.md, "Dwell").
N10 G0 X0 Y0 Z2 M3 S1200
N20 G1 Z-3 F200
N30 G4 F1.5                 ; 1.5 s at the bottom of the hole
N40 G0 Z2
N50 G4 F2
N60 R1=0.25
N70 G4 FR1
N80 G1 X10 F300
N90 G4
N100 G4 X1 F1
N110 M30
