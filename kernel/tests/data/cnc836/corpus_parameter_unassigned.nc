; EXPECT 2:4 R9 is used before
G0 XR9
