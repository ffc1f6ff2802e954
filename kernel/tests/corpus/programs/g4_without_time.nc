; EXPECT 3:5 needs its time
N10 G1 X1 F100
N20 G4
