#!/usr/bin/env bash
# deps.sh: installs the Debian 12 packages ipsd needs that are missing (apt-get, as root or via
# sudo). Idempotent: does nothing when everything is there. Sourced by run.sh and test.sh.
set -euo pipefail

IPSD_PACKAGES=(
    build-essential cmake pkg-config        # the build
    libgsl-dev libjansson-dev               # fit/ and JSON
    liblapacke-dev libopenblas0-pthread     # fit/'s least squares: LAPACK's C interface, and
                                            # OpenBLAS's thread-safe build (fit/ runs it on one
                                            # thread per call; the serial build is not safe to
                                            # call from two threads: CMakeLists.txt)
    libopenblas-pthread-dev libgfortran-12-dev  # their archives: ips links LAPACK statically
    libsqlite3-dev sqlite3                  # storage/ (and the sqlite3 shell, tests/docs use it)
    postgresql libpq-dev                    # storage/'s PostgreSQL backend (libpq), and the
                                            # server its tests start (tests/pg_server.sh)
    openssl                                 # that server's TLS certificate (tests/pg_server.sh)
    libmicrohttpd-dev                       # api/
    nettle-dev                              # server/: SHA-256 of the bearer tokens
    libcamera-dev                           # instrument/ libcamera backend (optional at build)
    libaravis-dev libusb-1.0-0-dev          # instrument/ Aravis backend for GenICam cameras
                                            # (optional at build; Debian's aravis-0.8.pc needs
                                            # libusb-1.0.pc, which libaravis-dev does not pull);
                                            # its GigE Vision emulator runs the camera tests
    curl wrk python3                        # HTTP tests, load benchmark, test scripts
    libcfitsio-dev                          # export/: FITS files of the maps
    python3-astropy                         # the FITS test reads the files back with astropy
    python3-numpy python3-scipy             # bench/numpy_peer.py (the NumPy peer of the fit)
    chromium                                # the dashboard's browser test (headless)
    clang                                   # scripts/build-matrix.sh's second compiler
)
# node and npm run the browser test's driver (playwright-core from the npm registry). Machines
# that already have a node (e.g. from nodesource) keep it: Debian's npm conflicts with that one.
command -v node >/dev/null 2>&1 || IPSD_PACKAGES+=(nodejs npm)

missing=()
for p in "${IPSD_PACKAGES[@]}"; do
    status=$(dpkg-query -W -f='${Status}' "$p" 2>/dev/null || true)
    [[ "$status" == "install ok installed" ]] || missing+=("$p")
done

if ((${#missing[@]})); then
    echo "ipsd: installing missing Debian packages: ${missing[*]}"
    if [[ $(id -u) -eq 0 ]]; then SUDO=(); elif command -v sudo >/dev/null; then SUDO=(sudo); else
        echo "ipsd: need root (or sudo) to run: apt-get install ${missing[*]}" >&2
        exit 1
    fi
    export DEBIAN_FRONTEND=noninteractive
    "${SUDO[@]}" apt-get update -qq
    "${SUDO[@]}" apt-get install -y -qq --no-install-recommends "${missing[@]}"
fi
