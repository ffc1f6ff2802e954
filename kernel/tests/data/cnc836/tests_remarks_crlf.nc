; program header
N10 G0 X10 ; rapid
N20 G1 X20 F100 "cut

