; docs/setup.md: entry 1 holds the part zero in X and Y (touch-off); go there.
N10 &1 G1 X0 Y0 F3000
N20 M30
