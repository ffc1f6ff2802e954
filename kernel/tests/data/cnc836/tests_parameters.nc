; kernel/tests/lang_program.rs: parameters keep their decimal point.
R1=1000 R2=1.5 R3=-2
G1 XR3 FR1
X-R3 FR2
R4=R2 YR4
R5=R4 R6=-R5 G0 XR6 Y-R6
N4 G0 XR9
