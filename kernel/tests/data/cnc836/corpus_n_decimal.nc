; EXPECT 2:1 N takes a whole number
N1.5 G0
