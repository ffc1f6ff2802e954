; EXPECT 2:8 stands in a block of its own
N10 L1 G0 X5
M30
%L1
M17
