; OFFSET 01: R=5.0 X=1.0
; EXPECT 4:1 length offset changed
&1
G2 X10 Y0 I5 J0 F100
