; EXPECT 2:1 no feed
N1 G1 X10
