; SETUP lathe
; EXPECT 3:1 third axis
G18
