; EXPECT 2:1 dwell
G4 X1
