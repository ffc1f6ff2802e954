; OFFSET 12: R=1.0 X=11.0 Y=12.0 Z=13.0 U=14.0
; kernel/tests/lang_program.rs: the compensation checks of the interpreter.
D12 G41 G1 X10 F100
G18
G42 X20
G40 Z5
G41 G2 X20 Y0 I5 J0
G40 X30
