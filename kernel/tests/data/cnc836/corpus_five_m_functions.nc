; EXPECT 2:13 more than 4 M
M1 M2 M3 M8 M9
