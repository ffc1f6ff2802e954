; EXPECT 2:8 feed F is zero
G1 X10 F0
