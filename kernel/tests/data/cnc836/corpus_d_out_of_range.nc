; EXPECT 2:1 D100 is outside 0..99
D100
