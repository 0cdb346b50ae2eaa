#!/usr/bin/env bash
# Install what the test suite needs, then run it. Safe to run again: it only
# installs what is missing. Used by the README and by .ci/run.
set -euo pipefail
cd "$(dirname "$0")/.."

# Debian packages for the firmware build and the simavr firmware-in-the-loop tests, and
# Chromium for the browser evenings of `serve` (Playwright drives it: its own browser
# download is never used).
DEBIAN_PACKAGES="gcc-avr avr-libc arduino-core-avr arduino-mk simavr libsimavr-dev chromium"
missing=""
for package in $DEBIAN_PACKAGES; do
    dpkg -s "$package" >/dev/null 2>&1 || missing="$missing $package"
done
if [ -n "$missing" ]; then
    if [ "$(id -u)" = 0 ] && command -v apt-get >/dev/null; then
        echo "installing Debian packages:$missing"
        export DEBIAN_FRONTEND=noninteractive
        apt-get update -qq
        apt-get install -y -qq $missing >/dev/null
    else
        echo "warning: missing Debian packages:$missing (firmware tests will say so)" >&2
    fi
fi

python3 -m pip install --quiet --disable-pip-version-check -e '.[test]'
# A worker per core and one more (pytest-xdist): many tests wait on the wall clock
# (paced simulators, a silent board's timeouts), and the extra worker runs meanwhile
# (docs/testing.md). A test file per worker at a time: a file's fixtures (a built
# firmware, a board's session) are made once. `-n 0` runs serially.
# The 20 slowest tests are listed at the end, to keep an eye on the suite's time.
workers=$(python3 -c 'import os
cores = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count()
print((cores or 1) + 1)')
exec python3 -m pytest -n "$workers" --dist loadfile --durations=20 "$@"
