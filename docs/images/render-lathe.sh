#!/bin/sh
# Renders the XZ previews of the lathe example programs (docs/lathe.md). Run from the
# repository root. The machine: axes X, Z; X programmed as a diameter (drawn as the radius,
# the true profile); R67 = 1, R329 d3 = 3; gears M41..M44 as programs/lathe/cncd-lathe.toml.
set -e
for p in manual_css turning_g95 facing_clamped profile_g41; do
    cargo run -q -p preview --example render -- "programs/lathe/$p.nc" "docs/images/lathe_$p.png" \
        --plane xz --axes XZ --diameter X \
        --const R0=1 --const R1=3 --const R2=0 --const R67=1 --const R329=0.3 \
        --gear 41:250 --gear 42:500 --gear 43:1000 --gear 44:2000
done
