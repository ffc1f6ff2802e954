; EXPECT 2:7 unexpected character '('
G0 X1 (comment)
