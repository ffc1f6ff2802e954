; EXPECT 2:1 S cannot be negative
S-100
