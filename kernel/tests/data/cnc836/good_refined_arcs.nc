; CONST R55=00000.001
; CONST R325=10000.010
; Seed 000 §7.2.5: E addresses as the preprocessor writes them, and an arc it refines itself
N10 G17 G90 G23 I2 F1500
N20 G3 X24.694108 Y0 I12.345 J0 E2.054
N30 G0 X0 Y0
N40 G2 X0 Y10.162016 I0 J5.088 E-10006.992
N50 G0 X0 Y0
N60 G3 X10 Y10 I0.003 J10 ; 3 µm off: refined by R325
N70 G1 X20 F.5 M37 ; 500 mm/min scaled to 5 mm/min
N80 R1=15 R2=1.2 G1 XR1 FR2 M36
