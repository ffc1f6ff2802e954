; EXPECT 2:5 address X has no value
N10 X
