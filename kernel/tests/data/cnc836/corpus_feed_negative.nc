; EXPECT 2:7 cannot be negative
G1 X1 F-5
