#!/usr/bin/env python3
"""test_readme.py IPS SOURCE_DIR: the `ips` commands README.md shows work as shown.

Reads the README's ```sh blocks, joins continued lines (a trailing backslash), and runs every
command line that starts with `build/cli/ips` with the build's ips in its place, from the source
directory (the README's paths are relative to it), /tmp replaced by a scratch directory. Each must
exit 0. Commands that need a running ipsd (curl) are not run here: the HTTP tests cover the routes
they use. Python 3 standard library only.
"""
import os
import re
import shutil
import subprocess
import sys
import tempfile


def commands(readme):
    out, block = [], None
    for line in open(readme, encoding="utf-8"):
        if line.startswith("```"):
            block = [] if block is None and line.strip() == "```sh" else None
            continue
        if block is None:
            continue
        out.append(line.rstrip("\n"))
    joined, cur = [], ""
    for line in out:
        line = re.sub(r"\s+#.*$", "", line) if not line.lstrip().startswith("-d") else line
        if line.endswith("\\"):
            cur += line[:-1] + " "
            continue
        joined.append((cur + line).strip())
        cur = ""
    return [c for c in joined if c.startswith("build/cli/ips ")]


def main():
    if len(sys.argv) != 3:
        sys.exit("usage: test_readme.py IPS SOURCE_DIR")
    ips, src = os.path.abspath(sys.argv[1]), os.path.abspath(sys.argv[2])
    cmds = commands(os.path.join(src, "README.md"))
    if len(cmds) < 4:
        print("test_readme: only %d ips commands found in README.md" % len(cmds))
        return 1
    scratch = tempfile.mkdtemp(prefix="ipsd-readme-")
    failed = 0
    try:
        for c in cmds:
            # /tmp/ first: the build's own path may lie under /tmp
            run = c.replace("/tmp/", scratch + "/").replace("build/cli/ips", shlex_quote(ips))
            r = subprocess.run(["bash", "-c", "set -o pipefail; " + run], cwd=src,
                               stdout=subprocess.PIPE, stderr=subprocess.PIPE, timeout=240)
            ok = r.returncode == 0
            print("%s: %s" % ("ok" if ok else "FAILED (exit %d)" % r.returncode, c))
            if not ok:
                failed += 1
                sys.stdout.write(r.stderr.decode(errors="replace")[-2000:])
        for f in ("scan.json", "truth.json", "fit.json", "map.fits"):
            p = os.path.join(scratch, f)
            if not (os.path.exists(p) and os.path.getsize(p)):
                print("FAILED: %s is empty" % f)
                failed += 1
    finally:
        shutil.rmtree(scratch, ignore_errors=True)
    print("test_readme: %d of %d README commands failed" % (failed, len(cmds)))
    return 1 if failed else 0


def shlex_quote(s):
    return "'" + s.replace("'", "'\\''") + "'"


if __name__ == "__main__":
    sys.exit(main())
