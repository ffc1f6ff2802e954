; EXPECT 2:7 above the limit 90000
G1 X1 F95.0
