; EXPECT 2:1 needs D<entry>
G92 R0=5
