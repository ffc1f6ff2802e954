; EXPECT 2:4 dwell
G4 X1
