; EXPECT 2:1 turning spindle
G95 G1 X1 F200
