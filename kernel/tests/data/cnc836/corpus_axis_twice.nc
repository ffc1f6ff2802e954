; EXPECT 2:7 axis X is written twice
G0 X1 X2
