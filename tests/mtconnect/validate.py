#!/usr/bin/env python3
"""Validates every MTConnect document in a directory against the official 2.5 schemas.

usage: validate.py SCHEMA_DIR DOC_DIR

Each *.xml file is checked against the schema of its root element (MTConnectDevices,
MTConnectStreams, MTConnectAssets, MTConnectError). Exits non-zero naming every file that
fails, with the reason and the path of the first error; with no documents at all it fails too.
"""
import pathlib
import sys
import xml.etree.ElementTree as ET

import xmlschema

KINDS = ("Devices", "Streams", "Assets", "Error")


def main() -> int:
    schema_dir, doc_dir = map(pathlib.Path, sys.argv[1:3])
    schemas = {}
    for kind in KINDS:
        path = schema_dir / f"MTConnect{kind}_2.5.xsd"
        # Streams and Assets have time-series restrictions xmlschema rejects when it builds
        # the schema: built leniently, the documents are still checked strictly against the
        # rest (the schemas' README).
        lax = "lax" if kind in ("Streams", "Assets") else "strict"
        schemas[kind] = xmlschema.XMLSchema11(str(path), validation=lax)
    docs = sorted(doc_dir.rglob("*.xml"))
    if not docs:
        print(f"FAIL: no MTConnect documents in {doc_dir}", file=sys.stderr)
        return 1
    failed = 0
    counts = dict.fromkeys(KINDS, 0)
    for d in docs:
        root = ET.parse(d).getroot().tag.split("}")[-1]
        kind = root.removeprefix("MTConnect")
        if kind not in schemas:
            print(f"FAIL {d}: root element {root} is not an MTConnect document", file=sys.stderr)
            failed += 1
            continue
        try:
            schemas[kind].validate(str(d))
            counts[kind] += 1
        except xmlschema.XMLSchemaValidationError as e:
            failed += 1
            print(f"FAIL {d}: {e.reason} at {e.path}", file=sys.stderr)
    print(f"validated {len(docs) - failed} of {len(docs)} documents against the MTConnect 2.5 "
          f"schemas ({', '.join(f'{k} {v}' for k, v in counts.items())})")
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
