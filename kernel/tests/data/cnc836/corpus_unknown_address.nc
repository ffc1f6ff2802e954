; EXPECT 3:5 unknown address Q
N10 G1 X1 F100
N20 Q5
