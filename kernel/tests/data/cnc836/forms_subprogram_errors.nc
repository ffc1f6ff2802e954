; Subprogram forms written wrong: each error has its code.
N10 G0 X1
N20 L9                      ; no %L9
N30 L1 X5                   ; a call stands alone
N40 P2                      ; P without L
N50 M17                     ; not in a subprogram
N60 L3
N70 M30
%L0
%L1
N100 G0 X2
N110 M17 X3
%L3
N300 L3                     ; calls itself until the nesting limit
N310 M17
%L1
M17
