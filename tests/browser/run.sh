#!/usr/bin/env bash
# Browser HMI suite (issue #30): real headless Chromium (Debian's chromium and chromium-driver,
# installed with apt when missing) driven by Selenium (pip, in a venv under target/) against
# a cargo-built cncd on the simulated machine, through its HMI origin (tests/browser/lib.sh:
# temporary data directory, free loopback ports, an operator token, a 5 mm following window).
# Saves the Run and Preview screenshots to docs/images/hmi_run.png and hmi_preview.png, and the
# Czech Run screen at each panel size to docs/images/hmi_run_WxH.png (issue #51).
# Exits non-zero on failure; the last line is "N passed, M failed".
set -euo pipefail
cd "$(dirname "$0")/../.."
ROOT=$PWD
. tests/browser/lib.sh

install_browser
start_cncd dev

mkdir -p docs/images "$TARGET_DIR/browser"
set +e
CNC_HMI_URL="http://127.0.0.1:$HMI_PORT/" CNC_TOKEN="$TOKEN" CNC_ADMIN_TOKEN="$ADMIN_TOKEN" CNC_SHOTS="$ROOT/docs/images" \
  CNC_FAIL_SHOTS="$TARGET_DIR/browser" "$VENV/bin/python" tests/browser/hmi_test.py
RC=$?
set -e
if [ $RC -ne 0 ]; then
  echo "--- cncd log (last 30 lines); failure screenshots in $TARGET_DIR/browser"
  tail -n 30 "$WORK/cncd.log" || true
fi
exit $RC
