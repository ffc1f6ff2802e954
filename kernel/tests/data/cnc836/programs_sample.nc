; Sample part: face a 60 x 40 mm plate in zig-zag passes, then a contour at Z-1.
; Units: mm. Feed without a decimal point is mm/min (F.6 would be 0.6 m/min).
N10 G0 X0 Y0 Z5
N20 G0 Z0.5
N30 G1 Z0 F300
N40 X60 F1800
N50 Y10
N60 X0
N70 Y20
N80 X60
N90 Y30
N100 X0
N110 Y40
N120 X60
N130 G0 Z5
N140 X5 Y5
N150 G1 Z-1 F300
N160 X55 F1200
N170 Y35
N180 X5
N190 Y5
N200 G0 Z5
N210 X0 Y0
