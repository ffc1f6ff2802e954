; IJ absolute
; EXPECT 4:1 not on the circle
G0 X5 Y0
G3 X25 Y0 I10 J0 F100
