; EXPECT 2:8 axis motion
G92 D1 X5 R0=1
