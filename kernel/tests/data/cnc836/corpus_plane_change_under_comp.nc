; EXPECT 3:1 plane cannot change
D1 G41 G1 X10 F100
G18 X20
