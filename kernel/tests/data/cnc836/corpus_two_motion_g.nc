; EXPECT 2:4 two G functions of the motion
G0 G1 X1
