; EXPECT 3:1 no call to return from
N10 G1 X1 F100
N20 M17
