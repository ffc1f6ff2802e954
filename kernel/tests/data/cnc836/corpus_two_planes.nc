; EXPECT 2:5 plane (G17..G19) group
G17 G18
