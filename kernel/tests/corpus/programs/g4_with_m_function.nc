; EXPECT 3:11 stands in a block of its own
N10 G1 X1 F100
N20 G4 F2 M8
