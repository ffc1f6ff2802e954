; EXPECT 4:1 subprogram L1 has no end
N10 L1
N20 M30
%L1
N100 G0 X5
