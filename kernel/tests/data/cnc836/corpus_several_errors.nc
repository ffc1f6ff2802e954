; EXPECT 4:4 unknown address Q
; EXPECT 5:1 no feed
; EXPECT 6:10 axis X is written twice
N1 Q1
N2 G1 X1
N3 G0 X1 X2
