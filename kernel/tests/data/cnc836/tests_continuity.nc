; kernel/tests/lang_program.rs: continuity and dynamic sets; I is the centre in a moving arc.
G1 X1 F100
G23 I2 X2
X3
G24 X4
G98 I4
G23 G2 X14 Y0 I5 J0
G23 I3
