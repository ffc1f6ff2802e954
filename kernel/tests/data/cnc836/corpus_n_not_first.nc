; EXPECT 2:4 N must be the first word
G0 N10 X1
