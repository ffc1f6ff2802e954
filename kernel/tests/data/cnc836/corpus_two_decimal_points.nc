; EXPECT 2:8 unexpected character '.'
G0 X1.2.3
