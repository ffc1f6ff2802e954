; EXPECT 2:1 radius is zero
G2 X10 Y0 I0 J0 F100
