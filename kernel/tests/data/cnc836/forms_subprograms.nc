; Subprograms and repeats (docs/language.md, "Subprograms and repeats"): two rows of three
; holes 15 mm apart, a dwell at the bottom of each hole.
N10 G0 X0 Y0 Z5 M3 S1500
N20 L1                      ; first row
N30 G0 X0 Y20
N40 L1                      ; second row
N50 G0 Z50 M5
N60 M30

%L1 ; a row of three holes
N100 L2 P3
N110 M17

%L2 ; one hole 7 mm deep, then 15 mm to the right
N200 G91 G1 Z-7 F150
N210 G4 F0.5
N220 G0 Z7
N230 X15
N240 G90
N250 M17
