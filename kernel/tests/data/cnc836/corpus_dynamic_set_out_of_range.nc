; EXPECT 2:5 outside 1..4
G23 I5
