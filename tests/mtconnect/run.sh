#!/usr/bin/env bash
# MTConnect suite (issue #33): runs the agent's tests (an in-process daemon on the simulated
# machine read through HTTP while programs run; the pure part's unit tests), which save every
# document the agent served, then validates each against the official MTConnect 2.5 XML
# schemas with Python's xmlschema (they are XSD 1.1: xmllint cannot read them).
#
# The schemas are not in this repository (AMT's licence): they are looked for in
# $CNC_MTCONNECT_SCHEMAS, default ../shared/mtconnect/ beside the repository. Without them the
# suite FAILS (it does not skip): the documents would go unchecked.
# Installs xmlschema into a virtual environment under target/ if needed.
set -euo pipefail
cd "$(dirname "$0")/../.."
ROOT=$(pwd)

SCHEMAS=${CNC_MTCONNECT_SCHEMAS:-$ROOT/../shared/mtconnect}
for kind in Devices Streams Assets Error; do
  if [ ! -f "$SCHEMAS/MTConnect${kind}_2.5.xsd" ]; then
    echo "FAIL: the MTConnect 2.5 schemas are missing: no $SCHEMAS/MTConnect${kind}_2.5.xsd" >&2
    echo "      (put the official schemas there, or set CNC_MTCONNECT_SCHEMAS)" >&2
    exit 1
  fi
done

PY=${PYTHON:-python3}
VENV="$ROOT/target/mtconnect-venv"
if ! "$VENV/bin/python" -c 'import xmlschema' 2>/dev/null; then
  echo "installing xmlschema into $VENV"
  if ! "$PY" -m venv "$VENV" 2>/dev/null; then
    # Debian ships venv apart (python3-venv).
    echo "installing python3-venv"
    apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq python3-venv
    rm -rf "$VENV"
    "$PY" -m venv "$VENV"
  fi
  "$VENV/bin/python" -m pip install --quiet xmlschema
fi

DOCS="$ROOT/target/mtconnect-docs"
rm -rf "$DOCS"
export CNC_MTCONNECT_DOCS="$DOCS"
echo "running the MTConnect tests (documents saved in $DOCS)"
# --workspace: the package set of scripts/test-all.sh's build, so nothing compiles again.
cargo test --quiet --locked --workspace --test mtconnect_agent
cargo test --quiet --locked --workspace --lib mtconnect
echo "validating against the schemas in $SCHEMAS"
"$VENV/bin/python" tests/mtconnect/validate.py "$SCHEMAS" "$DOCS"
