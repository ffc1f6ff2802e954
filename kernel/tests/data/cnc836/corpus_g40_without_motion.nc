; EXPECT 3:1 G40 must be in a block
D1 G41 G1 X10 F100
G40
