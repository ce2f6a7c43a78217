"""debian_python.py: Debian's python3-astropy (and python3-numpy) are installed for Debian's own
/usr/bin/python3. A test that reads FITS files with astropy and finds it missing calls
rerun_under_debian_python() from its ImportError handler: when it runs under another interpreter
(pyenv, a virtualenv), it starts again under /usr/bin/python3 with the same arguments; else the
call returns and the test decides (skip, or go on without the read-back)."""
import os
import sys

DEBIAN_PYTHON = "/usr/bin/python3"


def rerun_under_debian_python():
    """Replaces this process by the same test under DEBIAN_PYTHON, unless it already is that."""
    if os.path.exists(DEBIAN_PYTHON) and \
            os.path.realpath(sys.executable) != os.path.realpath(DEBIAN_PYTHON):
        os.execv(DEBIAN_PYTHON, [DEBIAN_PYTHON, "-B"] + sys.argv)
