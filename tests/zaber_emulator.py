#!/usr/bin/env python3
"""zaber_emulator.py: emulated Zaber devices speaking the Zaber ASCII protocol, for the tests of
ipsd's "zaber" stage backend (instrument/stage_zaber.c). Python standard library only.

Written from Zaber's published protocol descriptions ("Zaber's ASCII Protocol",
zaber.com/articles/ascii-protocol; the ZaberWiki "ASCII" page; the ASCII Protocol Manual's
command, reply-flag and warning-flag reference), not from the backend's code:
  - a command is "/DEVICE AXIS COMMAND ARGS" ended by CR, LF or both; axis 0 (or none) is the
    whole device; a device answers only commands to its own number (or to all, "/" alone);
  - every command gets one reply, ended by CR LF: "@DD A OK|RJ BUSY|IDLE FLAG DATA" (DD the
    device's two-digit number, FLAG the axis's highest warning flag, "--" for none; DATA the
    value asked for, 0 when there is none, the rejection reason after RJ: BADCOMMAND unknown
    command, BADDATA data out of range or not a number, BADAXIS no such axis, DEVICEONLY a device
    setting asked of an axis);
  - info messages "#DD A TEXT" may follow a reply, alerts "!DD A STATUS FLAG" come unasked (when a
    move ends, with alerts on);
  - "move abs N" (microsteps; outside limit.min .. limit.max: RJ BADDATA), "home" (to the home
    sensor at 0; sets the reference position), "stop", "get pos", "get limit.min",
    "get limit.max", "get deviceid", "get version", "warnings" / "warnings clear" (the axis's
    flags as "NN F1 F2 ..."; clear keeps WR while there is no reference position), and the empty
    command (the status reply only);
  - warning flags: WR no reference position, FS stalled and stopped, WL unexpected limit switch,
    NI a move interrupted (by "stop", a new move or the manual knob); faults (F*) outrank
    warnings (W*), which outrank notices (N*).

Motion is deterministic, not timed: a move or homing ends at the --polls-th status query of its
axis ("/D A" or "get pos"), positions on the way in proportion. Faults to inject (counting the
moves of all axes, "move abs" and "home"): --unhomed (no reference position at power-on: WR),
--reject CMD:N:REASON (the N-th command starting with CMD is rejected with REASON), --stall N (the
N-th move stops halfway with FS), --interrupt N (the N-th move stops halfway with NI, as a turn of
the knob does), --limit-hit N (the N-th move ends with WL), --drop-after-mov N (the first status
query after the N-th move closes the connection), --silent-after-mov N (after the N-th move
nothing is answered any more), --chatty (alerts after every move, an info line after every
"warnings" reply: a host must skip both).

Devices: --device D:K (device number D with K axes; repeat for a daisy chain; default 1:3).
Transports (tests/emu_serve.py): --tcp PORT (127.0.0.1; 0 picks a free port; connections served
one after the other, the devices' state lives on) or --pty (a pseudo-terminal). The first line on
stdout says where: "tcp PORT" or "pty /dev/pts/N". The emulator exits at the end of its stdin or
on SIGTERM.
"""
import argparse
import sys

from emu_serve import Drop, add_transport, run


class Axis:
    def __init__(self, a):
        self.lo, self.hi = a.limits
        self.pos = 0.0
        self.start = self.target = 0.0
        self.polls = 0  # status queries left until the move ends
        self.end_flag = None  # the flag the move ends with (FS, NI, WL), if any
        self.end_at = None  # where a faulty move stops
        self.flags = {"WR"} if a.unhomed else set()


class Devices:
    def __init__(self, a):
        self.a = a
        self.dev = {}
        for spec in a.device or ["1:3"]:
            d, k = (int(v) for v in spec.split(":"))
            self.dev[d] = [Axis(a) for _ in range(k)]
        self.counts = {}
        self.reject = {}
        for spec in a.reject or []:
            cmd, n, reason = spec.split(":")
            self.reject[(cmd, int(n))] = reason
        self.n_mov = 0
        self.silent = False
        self.drop_pending = False
        self.pending = []  # alerts and info lines to send after the reply

    @staticmethod
    def top_flag(flags):
        for level in "FWN":
            for f in sorted(flags):
                if f[0] == level:
                    return f
        return "--"

    def reply(self, d, ax, rejected, data, axes):
        busy = any(x.polls > 0 for x in axes)
        flags = set().union(*(x.flags for x in axes)) if axes else set()
        return "@%02d %d %s %s %s %s" % (d, ax, "RJ" if rejected else "OK",
                                          "BUSY" if busy else "IDLE", self.top_flag(flags), data)

    def advance(self, d, i, x):
        """One status query of motion time for axis x."""
        if x.polls <= 0:
            return
        if self.drop_pending:
            self.drop_pending = False
            raise Drop()
        x.polls -= 1
        if x.polls == 0:
            x.pos = x.end_at if x.end_at is not None else x.target
            if x.end_flag:
                x.flags.add(x.end_flag)
            if self.a.chatty:
                self.pending.append("!%02d %d IDLE %s" % (d, i + 1, self.top_flag(x.flags)))
        else:
            f = 1 - x.polls / self.a.polls
            x.pos = x.start + f * (x.target - x.start)

    def begin_move(self, x, target, home=False):
        if x.polls > 0:  # a new move interrupts the one under way
            x.flags.add("NI")
        self.n_mov += 1
        x.start, x.target, x.polls = x.pos, target, self.a.polls
        x.end_flag = x.end_at = None
        if home:
            x.flags.discard("WR")
        if self.n_mov in (self.a.stall, self.a.interrupt):
            x.end_flag = "FS" if self.n_mov == self.a.stall else "NI"
            x.end_at = round(x.start + (target - x.start) / 2)
        if self.n_mov == self.a.limit_hit:
            x.end_flag = "WL"
        if self.n_mov == self.a.drop_after_mov:
            self.drop_pending = True
        if self.n_mov == self.a.silent_after_mov:
            self.silent = True

    def handle(self, line):
        """One message; returns the reply lines."""
        if self.a.verbose:
            print("zaber_emulator: <- %r" % line, file=sys.stderr)
        if not line.startswith("/"):
            return []
        words = line[1:].split()
        if not words:  # "/": every device answers
            return [self.reply(d, 0, False, "0", axes) for d, axes in sorted(self.dev.items())]
        try:
            d = int(words[0])
            ax = int(words[1]) if len(words) > 1 and words[1].isdigit() else 0
        except ValueError:
            return []
        if d not in self.dev:
            return []  # no such device on the chain: nobody answers
        rest = words[2:] if len(words) > 1 and words[1].isdigit() else words[1:]
        axes = self.dev[d]
        if ax > len(axes):
            return [self.reply(d, ax, True, "BADAXIS", [])]
        sel = axes if ax == 0 else [axes[ax - 1]]
        for i, x in enumerate(axes):
            if x in sel:
                self.advance(d, i, x)
        cmd = " ".join(rest)
        n = None
        for key in {" ".join(rest[:k]) for k in range(1, len(rest) + 1)}:
            n = self.counts[key] = self.counts.get(key, 0) + 1
            reason = self.reject.get((key, n))
            if reason:
                return [self.reply(d, ax, True, reason, sel)]
        ok = lambda data="0": [self.reply(d, ax, False, data, sel)]  # noqa: E731
        bad = lambda why: [self.reply(d, ax, True, why, sel)]  # noqa: E731
        if cmd == "":
            return ok()
        if rest[0] == "get" and len(rest) == 2:
            if rest[1] in ("deviceid", "version"):
                if ax != 0:
                    return bad("DEVICEONLY")
                return ok("30222" if rest[1] == "deviceid" else "7.38")
            if rest[1] in ("pos", "limit.min", "limit.max"):
                vals = ["%d" % round({"pos": x.pos, "limit.min": x.lo, "limit.max": x.hi}[rest[1]])
                        for x in sel]
                return ok(" ".join(vals))
            return bad("BADCOMMAND")
        if rest[0] == "move" and len(rest) == 3 and rest[1] == "abs":
            try:
                v = int(rest[2])
            except ValueError:
                return bad("BADDATA")
            if any(not x.lo <= v <= x.hi for x in sel):
                return bad("BADDATA")
            for x in sel:
                self.begin_move(x, v)
            return ok()
        if cmd == "home":
            for x in sel:
                self.begin_move(x, 0, home=True)
            return ok()
        if cmd == "stop":
            for x in sel:
                if x.polls > 0:
                    x.flags.add("NI")
                    x.polls, x.target = 0, x.pos
            return ok()
        if cmd in ("warnings", "warnings clear"):
            flags = set().union(*(x.flags for x in sel))
            out = ok(" ".join(["%02d" % len(flags)] + sorted(flags)))
            if cmd == "warnings clear":
                for x in sel:
                    x.flags &= {"WR"}  # no reference position stays until homed
            if self.a.chatty:
                self.pending.append("#%02d %d flags listed" % (d, ax))
            return out
        return bad("BADCOMMAND")


def respond(devs, line):
    """The reply bytes to one received message (CR, LF or both end it): its reply, then the
    alerts and info lines it gave rise to."""
    if devs.silent or not line.strip():
        return b""
    out = devs.handle(line.decode("ascii", "replace").strip())
    out += devs.pending
    devs.pending = []
    return "".join(o + "\r\n" for o in out).encode("ascii")


def main():
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    add_transport(p)
    p.add_argument("--device", action="append", help="D:K (device D with K axes)")
    p.add_argument("--limits", type=lambda s: [int(v) for v in s.split(":")],
                   default=[-250000, 250000], help="LO:HI of every axis (microsteps)")
    p.add_argument("--polls", type=int, default=3)
    p.add_argument("--unhomed", action="store_true")
    p.add_argument("--reject", action="append", help="CMD:N:REASON")
    p.add_argument("--stall", type=int, default=0)
    p.add_argument("--interrupt", type=int, default=0)
    p.add_argument("--limit-hit", type=int, default=0)
    p.add_argument("--drop-after-mov", type=int, default=0)
    p.add_argument("--silent-after-mov", type=int, default=0)
    p.add_argument("--chatty", action="store_true")
    p.add_argument("--verbose", action="store_true")
    a = p.parse_args()
    devs = Devices(a)
    run(a, lambda line: respond(devs, line), cr_ends_line=True)


if __name__ == "__main__":
    main()
