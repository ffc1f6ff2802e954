; EXPECT 2:4 spindle direction
M3 M4
