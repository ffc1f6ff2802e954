; kernel/tests/lang_program.rs: G92 fills entry 12, compensation takes its radius at once.
N10 G92 D12 R0=10.0 R2=25.5 R3=-5.0
N20 D12 G41 G1 X10 F100
N30 G40 X20
N40 D12
N50 G42 G1 X10 F100
N60 X20
N70 G40 X30
