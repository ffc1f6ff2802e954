; EXPECT 2:1 G7 is not a function
G7 X1
