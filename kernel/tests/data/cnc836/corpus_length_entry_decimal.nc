; EXPECT 2:1 & takes a whole number
&1.5
