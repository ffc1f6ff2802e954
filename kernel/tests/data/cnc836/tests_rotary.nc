; tests/tests/rotary_feed.rs: A is rotary (3600 pulses per revolution).
N10 G1 A180 F3600
N20 G1 X100 A360 F600
N30 G1 X10 F600
N40 G2 X20 A90 I5 J0
