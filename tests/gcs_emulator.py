#!/usr/bin/env python3
"""gcs_emulator.py: an emulated PI motion controller speaking GCS 2.0, for the tests of ipsd's
"gcs" stage backend (instrument/stage_gcs.c). Python standard library only.

Written from PI's published GCS 2.0 command descriptions (the "GCS Commands" chapter and the
error code list of PI's controller manuals, e.g. the C-884 DC motor controller user manual), not
from the backend's code:
  - a command is one ASCII line ended by LF; only queries (names ending in '?') reply;
  - every line of a multi-line reply but the last ends with a space before the LF;
  - axis queries answer "AXIS=VALUE" per axis, all axes when none is named;
  - a command with an error is not executed and only sets the error code that ERR? returns and
    clears: 1 parameter syntax error, 2 unknown command, 5 move on an unreferenced axis or with
    the servo off, 7 position out of limits, 10 stopped by command, 15 invalid axis identifier;
  - MOV (absolute move), ONT? (on target), POS? (position), SVO / SVO? (servo), FRF / FRF?
    (reference move, referenced?), TMN? / TMX? (soft travel limits), GOH (go to home, 0),
    STP (stop), SAI? (axis identifiers), *IDN? (identification).

Motion is deterministic, not timed: after a MOV the axes reach the target at the --ont-polls-th
ONT? query (POS? reports the way there in proportion); a reference move completes at the
--ref-polls-th FRF? query. Faults to inject: --fail CMD:N:CODE (the N-th CMD command fails with
error CODE), --servo-off / --unreferenced (the state at power-on), --servo-trip N (after the N-th
MOV the servo of the first axis switches off, as a following-error trip does), --drop-after-mov N
(the first ONT? after the N-th MOV closes the connection: a connection dropped mid-move),
--silent-after-mov N (after the N-th MOV nothing is answered any more: a hung controller).

Transports (tests/emu_serve.py): --tcp PORT (127.0.0.1; 0 picks a free port; connections are
served one after the other, the controller's state lives on between them) or --pty (a
pseudo-terminal; its slave is the "serial line"). The first line on stdout says where: "tcp PORT"
or "pty /dev/pts/N". The emulator exits when its stdin reaches end of file (so it never outlives
the test that runs it) or on SIGTERM.
"""
import argparse
import sys

from emu_serve import Drop, add_transport, run

ERR_SYNTAX, ERR_UNKNOWN, ERR_NO_SERVO, ERR_LIMITS, ERR_STOP, ERR_AXIS = 1, 2, 5, 7, 10, 15


class Controller:
    def __init__(self, a):
        self.axes = a.axes.split(",")
        self.lo = {x: a.travel[0] for x in self.axes}
        self.hi = {x: a.travel[1] for x in self.axes}
        for spec in a.travel_axis or []:
            name, rng = spec.split("=")
            self.lo[name], self.hi[name] = (float(v) for v in rng.split(":"))
        self.pos = {x: 0.0 for x in self.axes}
        self.start = dict(self.pos)
        self.target = dict(self.pos)
        self.servo = {x: not a.servo_off for x in self.axes}
        self.ref = {x: not a.unreferenced for x in self.axes}
        self.referencing = 0  # FRF? polls left until the reference move is done
        self.moving = 0  # ONT? polls left until on target
        self.err = 0
        self.counts = {}
        self.n_mov = 0
        self.silent = False
        self.drop_pending = False
        self.a = a
        self.fail = {}
        for spec in a.fail or []:
            cmd, n, code = spec.split(":")
            self.fail[(cmd, int(n))] = int(code)

    def set_err(self, code):
        if self.err == 0:  # the first error stays until ERR? reads it
            self.err = code

    def axes_of(self, args):
        """The axes a query names (all when none); None when one is not an axis."""
        if not args:
            return list(self.axes)
        return args if all(x in self.axes for x in args) else None

    def advance(self):
        """One ONT? poll of motion time."""
        if self.moving > 0:
            self.moving -= 1
            if self.moving == 0:
                self.pos = dict(self.target)
            else:
                f = 1 - self.moving / self.a.ont_polls
                for x in self.axes:
                    self.pos[x] = self.start[x] + f * (self.target[x] - self.start[x])

    def begin_move(self, targets):
        """MOV and GOH: all-or-nothing checks, then the move starts."""
        for x, v in targets.items():
            if not self.servo[x] or not self.ref[x]:
                return self.set_err(ERR_NO_SERVO)
            if not self.lo[x] <= v <= self.hi[x]:
                return self.set_err(ERR_LIMITS)
        self.start = dict(self.pos)
        self.target.update(targets)
        self.moving = self.a.ont_polls
        self.n_mov += 1
        if self.n_mov == self.a.servo_trip:
            self.servo[self.axes[0]] = False
        if self.n_mov == self.a.drop_after_mov:
            self.drop_pending = True
        if self.n_mov == self.a.silent_after_mov:
            self.silent = True

    def pairs(self, args):
        """AXIS VALUE pairs; None after setting the error."""
        if not args or len(args) % 2:
            return self.set_err(ERR_SYNTAX)
        out = {}
        for x, v in zip(args[::2], args[1::2]):
            if x not in self.axes:
                return self.set_err(ERR_AXIS)
            try:
                out[x] = float(v)
            except ValueError:
                return self.set_err(ERR_SYNTAX)
        return out

    def handle(self, line):
        """One command line; returns the reply lines (a list, empty for none)."""
        if self.a.verbose:
            print("gcs_emulator: <- %r" % line, file=sys.stderr)
        words = line.split()
        if not words:
            return []
        cmd, args = words[0], words[1:]
        n = self.counts[cmd] = self.counts.get(cmd, 0) + 1
        code = self.fail.get((cmd, n))
        if code:
            self.set_err(code)
            return []
        if cmd == "*IDN?":
            return ["(c) ipsd tests, GCS 2.0 controller emulator, 0, 1.0.0"]
        if cmd == "ERR?":
            e, self.err = self.err, 0
            return ["%d" % e]
        if cmd == "SAI?":
            return list(self.axes)
        if cmd in ("POS?", "ONT?", "SVO?", "FRF?", "TMN?", "TMX?"):
            axes = self.axes_of(args)
            if axes is None:
                self.set_err(ERR_AXIS)
                return []
            if cmd == "ONT?":
                if self.drop_pending:
                    self.drop_pending = False
                    raise Drop()
                self.advance()
                return ["%s=%d" % (x, int(self.moving == 0)) for x in axes]
            if cmd == "FRF?":
                if self.referencing > 0:
                    self.referencing -= 1
                    if self.referencing == 0:
                        for x in self.axes:
                            self.ref[x] = True
                return ["%s=%d" % (x, int(self.ref[x])) for x in axes]
            if cmd == "SVO?":
                return ["%s=%d" % (x, int(self.servo[x])) for x in axes]
            table = {"POS?": self.pos, "TMN?": self.lo, "TMX?": self.hi}[cmd]
            return ["%s=%+.7f" % (x, table[x]) for x in axes]
        if cmd == "SVO":
            p = self.pairs(args)
            if p is not None:
                if any(v not in (0.0, 1.0) for v in p.values()):
                    self.set_err(ERR_SYNTAX)
                else:
                    for x, v in p.items():
                        self.servo[x] = v == 1.0
            return []
        if cmd == "MOV":
            p = self.pairs(args)
            if p is not None:
                self.begin_move(p)
            return []
        if cmd in ("FRF", "GOH"):
            axes = self.axes_of(args)
            if axes is None:
                self.set_err(ERR_AXIS)
            elif cmd == "GOH":
                self.begin_move({x: 0.0 for x in axes})
            elif not all(self.servo[x] for x in axes):
                self.set_err(ERR_NO_SERVO)
            else:  # the reference switch is at 0
                for x in axes:
                    self.ref[x] = False
                    self.pos[x] = self.target[x] = 0.0
                self.referencing = self.a.ref_polls
            return []
        if cmd == "STP":
            self.target = dict(self.pos)
            self.moving = 0
            self.set_err(ERR_STOP)
            return []
        self.set_err(ERR_UNKNOWN)
        return []


def reply_bytes(lines):
    """GCS multi-line framing: every line but the last ends with ' \\n'."""
    if not lines:
        return b""
    return (" \n".join(lines) + "\n").encode("ascii")


def respond(ctl, line):
    """The reply bytes to one received line (LF-ended; a CR before the LF is dropped)."""
    if ctl.silent:
        return b""
    return reply_bytes(ctl.handle(line.decode("ascii", "replace").strip("\r")))


def main():
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    add_transport(p)
    p.add_argument("--axes", default="1,2,3")
    p.add_argument("--travel", type=lambda s: [float(v) for v in s.split(":")],
                   default=[-25.0, 25.0], help="LO:HI of every axis (controller units)")
    p.add_argument("--travel-axis", action="append", help="AXIS=LO:HI")
    p.add_argument("--ont-polls", type=int, default=3)
    p.add_argument("--ref-polls", type=int, default=2)
    p.add_argument("--servo-off", action="store_true")
    p.add_argument("--unreferenced", action="store_true")
    p.add_argument("--servo-trip", type=int, default=0)
    p.add_argument("--drop-after-mov", type=int, default=0)
    p.add_argument("--silent-after-mov", type=int, default=0)
    p.add_argument("--fail", action="append", help="CMD:N:CODE")
    p.add_argument("--verbose", action="store_true")
    a = p.parse_args()
    ctl = Controller(a)
    run(a, lambda line: respond(ctl, line))


if __name__ == "__main__":
    main()
