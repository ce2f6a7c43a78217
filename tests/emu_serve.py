"""emu_serve.py: the transport of the emulated stage controllers (tests/gcs_emulator.py,
tests/zaber_emulator.py): --tcp PORT (127.0.0.1; 0 picks a free port; connections are served one
after the other, the controller's state lives on between them) or --pty (a pseudo-terminal; its
slave is the "serial line"). The first line on stdout says where: "tcp PORT" or "pty /dev/pts/N".
The emulator exits when its stdin reaches end of file (so it never outlives the test that runs
it). What the lines mean is the emulator's: it gives a function from a received line to the bytes
to send back, which raises Drop to close the connection. Python standard library only."""
import os
import select
import socket
import sys
import tty


class Drop(Exception):
    """The connection is to be closed now (--drop-after-mov)."""


def add_transport(parser):
    """--tcp PORT or --pty, one of them required."""
    g = parser.add_mutually_exclusive_group(required=True)
    g.add_argument("--tcp", type=int, metavar="PORT")
    g.add_argument("--pty", action="store_true")


def _stdin_closed():
    return not os.read(sys.stdin.fileno(), 4096)


def serve(respond, rfd, write, cr_ends_line):
    """Reads lines from rfd (an fd or a socket) until it closes or respond raises Drop; exits the
    emulator when stdin closes. A line ends at LF (and at CR too with cr_ends_line); respond gets
    it without its LF and returns the bytes to write (b"" for none)."""
    fd = rfd if isinstance(rfd, int) else rfd.fileno()
    buf = b""
    while True:
        r, _, _ = select.select([fd, sys.stdin], [], [])
        if sys.stdin in r and _stdin_closed():
            sys.exit(0)
        if fd not in r:
            continue
        try:
            data = os.read(fd, 4096)
        except OSError:
            return
        if not data:
            return
        buf += data.replace(b"\r", b"\n") if cr_ends_line else data
        while b"\n" in buf:
            line, buf = buf.split(b"\n", 1)
            try:
                out = respond(line)
            except Drop:
                return
            if out:
                write(out)


def run(a, respond, cr_ends_line=False):
    """Serves respond on the transport the parsed arguments a name (add_transport's)."""
    if a.pty:
        master, slave = os.openpty()
        tty.setraw(slave)  # no echo, no line editing: a plain byte line, like a serial port
        print("pty %s" % os.ttyname(slave), flush=True)
        # the emulator keeps the slave open too, so the master never sees a hang-up when the
        # backend closes and reopens the line
        serve(respond, master, lambda b: os.write(master, b), cr_ends_line)
        return
    ls = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
    ls.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
    ls.bind(("127.0.0.1", a.tcp))
    ls.listen(4)
    print("tcp %d" % ls.getsockname()[1], flush=True)
    while True:
        r, _, _ = select.select([ls, sys.stdin], [], [])
        if sys.stdin in r and _stdin_closed():
            return
        if ls not in r:
            continue
        conn, _ = ls.accept()
        serve(respond, conn, conn.sendall, cr_ends_line)
        conn.close()
