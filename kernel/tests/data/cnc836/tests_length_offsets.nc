; OFFSET 12: R=1.0 X=11.0 Y=12.0 Z=13.0 U=14.0
; kernel/tests/lang_program.rs: & selects an entry's lengths; G92 changes them.
G0 X0 Y0 Z0
&12
G0 X1
G1 Z-1 F100
&0 G0 Z5
&12 G0 Z0
G92 D12 R3=-5.0
G0 Z0
G92 D12
