; EXPECT 2:1 G takes a whole number
G1.5 X1
