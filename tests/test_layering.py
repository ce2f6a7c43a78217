#!/usr/bin/env python3
"""test_layering.py SRC: the rooms' dependencies point inward, as docs/architecture.md draws them.

Every `#include "room/name.h"` in a room's sources is checked against the rooms it may use; a
room's internal headers are included by bare name and the build (build/include/ROOM/ holds only
public headers) already refuses them elsewhere. The exceptions are named here with their reason.
"""
import pathlib
import re
import sys

# room -> rooms its sources may include from (besides itself)
ALLOWED = {
    "base": set(),
    "fit": {"base"},
    "json": {"base", "fit"},
    "export": {"base"},
    "instrument": {"base", "fit"},
    "storage": {"base"},
    "server": {"base", "fit", "json", "instrument", "storage"},
    "api": {"base", "fit", "json", "export", "instrument", "storage", "server"},
    "cli": {"base", "fit", "json", "export", "instrument"},
    "bench": {"base", "fit", "json", "instrument", "storage"},
}
# single headers a room may include from a room it otherwise does not use: (room, header) -> why
EXCEPTIONS = {
    ("storage", "instrument/scan_limits.h"):
        "storage checks a scan row against the scan limits defined once in instrument/",
}

INCLUDE = re.compile(r'^\s*#\s*include\s+"([^"]+)"', re.M)


def main():
    src = pathlib.Path(sys.argv[1] if len(sys.argv) > 1 else ".")
    bad, checked = [], 0
    for room, allowed in ALLOWED.items():
        for f in sorted((src / room).glob("*")):
            if f.suffix not in (".c", ".h", ".cpp"):
                continue
            for name in INCLUDE.findall(f.read_text()):
                checked += 1
                if "/" not in name:  # bare name: must be a header of the same room
                    if not (f.parent / name).exists() and not name.endswith("_table.h") \
                            and name != "bench_scan.h":
                        bad.append(f"{f.relative_to(src)}: bare include \"{name}\" is not in {room}/")
                    continue
                other = name.split("/")[0]
                if other == room or other in allowed or (room, name) in EXCEPTIONS:
                    continue
                bad.append(f"{f.relative_to(src)}: {room}/ may not include \"{name}\"")
    for b in bad:
        print("FAIL:", b)
    print(f"{checked} includes checked, {len(bad)} against the layering")
    # the check must have seen the tree: an empty walk would pass vacuously
    if checked < 100:
        print(f"FAIL: only {checked} includes found under {src}: wrong source directory?")
        return 1
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main())
