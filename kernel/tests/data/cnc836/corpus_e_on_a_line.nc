; EXPECT 2:8 E refines an arc centre
G1 X10 E2.054 F100
