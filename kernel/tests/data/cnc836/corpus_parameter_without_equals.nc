; EXPECT 2:1 needs '='
R5 5
