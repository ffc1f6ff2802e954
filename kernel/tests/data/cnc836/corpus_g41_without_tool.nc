; EXPECT 2:4 needs a tool
N5 G41 G1 X10 F100
