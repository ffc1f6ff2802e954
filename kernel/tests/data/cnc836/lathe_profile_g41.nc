; Finishing a turned profile under tool-nose radius compensation, X programmed as a diameter
; (docs/lathe.md): face to Ø20, taper to Ø30, R5 fillet, cylinder Ø40, shoulder to Ø60. Tool
; nose R0.8 in entry 1 (written by G92: memory only), 0.15 mm/rev at 800 rpm.
; The plane of a two-axis lathe is G17 = (X, Z), X first: seen that way the outside of a part
; turned toward the chuck is LEFT of the path, so outside turning is G41 here (G42 on
; controls whose lathe plane is G18 = (Z, X)).
N5 G92 D1 R0=0.8
N10 G0 X100 Z5 M43 M3 S800
N20 G95 G41 D1 G1 X10 Z2 F0.15
N30 Z0
N40 X20
N50 X30 Z-15
N60 G3 X40 Z-20 I5 J0 "R5: I is a radius
N70 G1 Z-40
N80 X60
N90 G40 G1 X100 Z5
N100 G94 G0 X300 Z100
N110 M5
