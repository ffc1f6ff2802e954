; EXPECT 2:1 not on the circle
N30 G2 X10 Y1 I5 J0 F100
