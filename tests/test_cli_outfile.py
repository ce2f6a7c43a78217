#!/usr/bin/env python3
"""test_cli_outfile.py IPS: the output files of ips (base/outfile.h, here through `ips simulate
-o FILE --truth FILE`, the writer every scan-file command shares) never replace what is not a
regular file:
  - a regular file is replaced whole; a symbolic link stays a link and its target gets the scan;
    a link to nothing, a directory, or a PATH.tmp that is a link (to a victim file) are refused
    with exit 2 and one line, nothing written anywhere;
  - a FIFO is written in place (its reader gets the scan, the FIFO stays a FIFO); a null device
    stays a device; a full one fails with exit 1 and one line naming the disk full, the node
    kept (nodes of /dev/null's and /dev/full's numbers made here when this runs as root).
The scan's file is read back by Python's json (an independent reader) and compared with the one
written to a fresh path."""
import json
import os
import stat
import subprocess
import sys
import tempfile
import threading

from oklines import check, finish

SIM = ["simulate", "--seed", "3", "--area", "1", "--step", "1.2", "--subframe", "3",
       "--frames", "1"]


def load(path):
    """The JSON of a file, None when it holds none."""
    try:
        with open(path) as f:
            return json.load(f)
    except (OSError, ValueError):
        return None


def run(ips, out, *extra):
    return subprocess.run([ips] + SIM + ["-o", out] + list(extra), capture_output=True,
                          text=True, timeout=300)


def one_line(p, code, word, what):
    lines = p.stderr.strip().split("\n")
    return check(p.returncode == code and len(lines) == 1 and word in lines[0],
                 "%s: exit %d, one line naming %r (exit %d, %r)" % (what, code, word,
                                                                    p.returncode, p.stderr))


def main():
    ips = sys.argv[1]
    with tempfile.TemporaryDirectory() as t:
        fresh = os.path.join(t, "fresh.json")
        p = run(ips, fresh)
        check(p.returncode == 0, "a fresh file: exit 0 (%r)" % p.stderr)
        with open(fresh) as f:
            want = json.load(f)
        check(len(want["x_um"]) > 0, "the scan has points")

        # a regular file: replaced whole
        reg = os.path.join(t, "reg.json")
        with open(reg, "w") as f:
            f.write("old contents\n" * 1000)
        p = run(ips, reg)
        check(p.returncode == 0 and load(reg) == want, "a regular file is replaced")

        # a symbolic link: the target gets the scan, the link stays
        target, link = os.path.join(t, "target.json"), os.path.join(t, "link.json")
        with open(target, "w") as f:
            f.write("old\n")
        os.symlink(target, link)
        p = run(ips, link, "--truth", link + ".truth")
        check(p.returncode == 0 and os.path.islink(link) and os.readlink(link) == target,
              "a link stays a link (%r)" % p.stderr)
        check(load(target) == want, "the link's target holds the scan")
        tl = os.path.join(t, "truth-target.json")
        os.symlink(tl, os.path.join(t, "truth-link.json"))
        with open(tl, "w") as f:
            f.write("{}")
        p = run(ips, fresh, "--truth", os.path.join(t, "truth-link.json"))
        check(p.returncode == 0 and os.path.islink(os.path.join(t, "truth-link.json")) and
              "maps" in (load(tl) or {}), "--truth through a link: the link kept, the target "
              "written")

        # refused: a link to nothing, a directory, a PATH.tmp that is a link to a victim
        dangling = os.path.join(t, "dangling.json")
        os.symlink(os.path.join(t, "nowhere", "x.json"), dangling)
        one_line(run(ips, dangling), 2, "symbolic link to nothing", "a link to nothing")
        check(os.path.islink(dangling), "the dangling link is kept")
        d = os.path.join(t, "dir.json")
        os.mkdir(d)
        one_line(run(ips, d), 2, "directory", "a directory")
        check(os.path.isdir(d) and os.listdir(d) == [], "the directory is kept, empty")
        victim, out = os.path.join(t, "victim.txt"), os.path.join(t, "out.json")
        with open(victim, "w") as f:
            f.write("precious\n")
        os.symlink(victim, out + ".tmp")
        one_line(run(ips, out), 2, "not a regular file", "PATH.tmp a link to a victim")
        with open(victim) as f:
            check(f.read() == "precious\n", "the victim is untouched")
        check(not os.path.exists(out) and os.path.islink(out + ".tmp"), "nothing written")

        # a FIFO: written in place, its reader gets the scan
        fifo = os.path.join(t, "fifo.json")
        os.mkfifo(fifo)
        got = []
        # a daemon thread: if the FIFO were replaced its reader would wait for ever
        reader = threading.Thread(target=lambda: got.append(open(fifo).read()), daemon=True)
        reader.start()
        p = run(ips, fifo)
        reader.join(5 if not stat.S_ISFIFO(os.lstat(fifo).st_mode) else 120)
        check(p.returncode == 0 and stat.S_ISFIFO(os.lstat(fifo).st_mode),
              "a FIFO: exit 0, still a FIFO (%r)" % p.stderr)
        check(got and got[0].startswith("{") and json.loads(got[0]) == want,
              "the FIFO's reader got the scan")
        # devices: nodes with the numbers of /dev/null (1, 3) and /dev/full (1, 7) made here
        # (root only), never the machine's own, which a broken writer would replace
        null, full = os.path.join(t, "null"), os.path.join(t, "full")
        try:
            os.mknod(null, 0o666 | stat.S_IFCHR, os.makedev(1, 3))
            os.mknod(full, 0o666 | stat.S_IFCHR, os.makedev(1, 7))
        except OSError:
            print("skip the devices: cannot make a device node here")
        else:
            p = run(ips, null)
            check(p.returncode == 0 and stat.S_ISCHR(os.lstat(null).st_mode),
                  "a null device: exit 0, still a device (%r)" % p.stderr)
            one_line(run(ips, full), 1, "No space left on device", "a full device")
            check(stat.S_ISCHR(os.lstat(full).st_mode), "the device node is kept")
    finish()


if __name__ == "__main__":
    main()
