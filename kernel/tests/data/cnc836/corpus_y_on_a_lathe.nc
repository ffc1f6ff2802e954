; SETUP lathe
; EXPECT 3:4 unknown address Y
G0 Y5
