"""The machine of issue #32, shared by reference.py and hold_estimate.py (the same figures as
machine.rek): per axis 20000 mm/min and 1000 mm/s², no path-level acceleration (R52 = R237 =
0: the axes' limits), F6000, R384 Lm = 8 µm, R385 am = 1000 mm/s², 4 ms ticks. Plain numbers,
and the junction criteria of ticks.py and jerk_ticks.py, so a script that needs no TOPP-RA can
import them."""

import math

V_AXIS = 20000.0 / 60.0
A_AXIS = 1000.0
FEED = 6000.0 / 60.0
LM_MM = 0.008
AM = 1000.0
TS = 0.004


def criteria_cap_mm_s(chord):
    """The speed of a step crossing a junction whose unit tangents differ by `chord` (> 0): the
    manual's dynamic criterion R385 (am·Ts/|Δt|) and accuracy criterion R384 (Lm over a tick
    at the half angle's tangent)."""
    half = math.asin(min(chord / 2, 1.0))
    tan = math.tan(half) if chord < 2 - 1e-12 else math.inf
    return min(AM * TS / chord, LM_MM / (TS * tan))
