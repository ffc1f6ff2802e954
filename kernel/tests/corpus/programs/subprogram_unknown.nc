; EXPECT 3:1 subprogram L7 is not in the program
N10 G1 X1 F100
N20 L7
%L6
M17
