; MIKROPROG user guide, example for G41/G42/G40: mill the outside of a template ("sablona")
; with a 10 mm end mill; start position X-30 Y0; no Z motion.
; The guide keeps N30, N40, N50, N110, N120 and N130; its drawing and blocks N60..N100 are lost.
; N60..N100 are our reconstruction (docs/compensation.md): convex and concave arcs, a tangent
; and non-tangent corners, run clockwise round the template so that G41 (tool left of the
; path, "compensation from the right") cuts the outside.
; Tool: D1 holds radius 5.0 (written here with G92, memory only, SPEC section 3).
N10 G92 D1 R0=5.0             ; tool change - end mill 10 mm
N20 G17 D1 M3 S1000           ; spindle on
N30 G41                       ; compensation on (takes effect in the first linear move)
N40 G1 X0 F100                ; approach to the template surface
N50 G1 Y20                    ; mill the template
N60 G2 X20 Y40 I20 J0         ; convex arc R20, tangent to N50 and N70
N70 G1 X40
N80 G1 Y25                    ; outside corner of 90 degrees
N90 G3 X55 Y10 I15 J0         ; concave fillet R15, tangent to N80 and N100's start direction
N100 G1 X80 Y0                ; outside corner of 22 degrees
N110 G1 X0                    ; sharp outside corner of 158 degrees, back to the start point
N120 G40 G1 X-10              ; compensation off (the guide writes G40 alone: needs 7.R339 = 1)
N130 G0 X-30                  ; back to the start position
N140 M5
