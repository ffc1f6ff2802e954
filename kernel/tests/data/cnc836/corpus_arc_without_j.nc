; EXPECT 2:11 both centre words
G2 X10 Y0 I5 F100
