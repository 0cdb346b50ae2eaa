"""Stock GRBL 1.1h in the simavr harness: build it (its own Makefile, in a temp
folder) and run it as a SimulatedBoard with its pins traced and simavr's timer
quirks corrected (docs/harness.md "Timer quirks", docs/grbl.md).

The GRBL source is $GALILEO_GRBL_SOURCE if set, else a checkout's unmodified
copy, third_party/grbl-1.1h (a GPL-3 test fixture, never part of the package):
the checkout the package runs from, else the current directory's (after
`pip install .` the package runs from the venv, whose folders hold no GRBL), else
`../shared/grbl-1.1h` beside either. It is built in a temporary folder and the ELF
cached in the checkout's firmware/build-grbl/ (ignored by git), or, installed
without a checkout, in the user's cache folder, with the source digest it came
from.
Lives beside the harness so `simavr://?firmware=grbl` (protocol_simavr) can use
it; galileo_cnc.grbl.firmware re-exports it.
"""

from __future__ import annotations

import hashlib
import math
import os
import re
import shutil
import subprocess
import tempfile
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from galileo_cnc.errors import GalileoError
from galileo_cnc.simavr.board import (REPO_ROOT, SimulatedBoard, checkouts,
                                      missing_debian_packages, step_trace)
from galileo_cnc.simavr.build_lock import build_lock

GRBL_SOURCE_ENV = "GALILEO_GRBL_SOURCE"
GRBL_SOURCE_URL = "https://github.com/gnea/grbl/releases/tag/v1.1h.20190825"


def source_places() -> list[Path]:
    """Where the source is looked for, unless $GALILEO_GRBL_SOURCE names it, in order:
    each checkout's third_party/grbl-1.1h, then ../shared/grbl-1.1h beside it."""
    roots = [REPO_ROOT] + [root for root in checkouts() if root != REPO_ROOT.resolve()]
    places = [root / "third_party" / "grbl-1.1h" for root in roots]
    return places + [root.parent / "shared" / "grbl-1.1h" for root in roots]


def _is_source(place: Path) -> bool:
    return (place / "Makefile").is_file() and (place / "grbl" / "grbl.h").is_file()


#: the source found at import (source_dir() looks again, the current folder included)
SOURCE_PLACES = tuple(source_places())
DEFAULT_SOURCE = next((place for place in SOURCE_PLACES if _is_source(place)),
                      SOURCE_PLACES[0])
BUILD_DIR = REPO_ROOT / "firmware" / "build-grbl"
ELF_NAME = "grbl.elf"
BUILD_PACKAGES = ("gcc-avr", "avr-libc", "make")

# GRBL's Uno pin map (cpu_map.h): X/Y/Z step D2-D4, dir D5-D7 (high = negative
# with the stock $3=0), limits D9/D10/D12 (pulled up, low = triggered).
AXIS_PINS: tuple[tuple[int, int], ...] = ((2, 5), (3, 6), (4, 7))
LIMIT_PINS = (9, 10, 12)
SPINDLE_PWM_PIN = 11
# GRBL's probe input (cpu_map.h PROBE_BIT 5 of PORTC: A5, Arduino 19), pulled up;
# with the stock $6=0 a low pin is touching (probe.c probe_get_state).
PROBE_PIN = 19
TRACE_PINS = (2, 3, 4, 5, 6, 7)
# OCR1A at cycle 0: any small TOP lets the first step interrupt fire; GRBL sets
# its own value there.
OCR1A_AT_START = 16
HARNESS_ARGS = ("--axis-pins", "X:2:5,Y:3:6,Z:4:7",
                "--ocr1a-at-start", str(OCR1A_AT_START), "--replay-tcnt0")


@dataclass(frozen=True)
class ProbeSurface:
    """The work surface the harness's probe pin touches (--probe), in GRBL's machine
    steps from power-up (GRBL's own sense: negative Z is down): touching while
    z <= z0 + amp sin(2 pi x/px) sin(2 pi y/py); amp 0 is flat at z0."""

    z0: float
    amp: float = 0.0
    px: float = 0.0
    py: float = 0.0

    @classmethod
    def parse(cls, text: str) -> "ProbeSurface":
        """`Z0` or `Z0:AMP:PX:PY` (ValueError if it is neither, or PX, PY are 0)."""
        fields = [float(field) for field in text.split(":")]
        if len(fields) not in (1, 4) or (len(fields) == 4 and fields[1]
                                         and not (fields[2] and fields[3])):
            raise ValueError(f"expected Z0 or Z0:AMP:PX:PY in steps (PX, PY not 0), "
                             f"got {text!r}")
        return cls(*fields)

    def height(self, x: float, y: float) -> float:
        """The surface's Z (steps) over machine (x, y) (steps); the harness evaluates
        the same formula in doubles."""
        if not self.amp:
            return self.z0
        return self.z0 + self.amp * math.sin(2 * math.pi * x / self.px) \
            * math.sin(2 * math.pi * y / self.py)

    def harness_args(self) -> tuple[str, ...]:
        fields = [self.z0] if not self.amp else [self.z0, self.amp, self.px, self.py]
        spec = ":".join(f"{field:g}" if field != int(field) else str(int(field))
                        for field in fields)
        return ("--probe", f"{PROBE_PIN}:{spec}", "--probe-dir-low-positive")


class GrblBuildError(GalileoError):
    """GRBL could not be built (missing source or toolchain, make failed)."""


def source_dir() -> Path:
    """$GALILEO_GRBL_SOURCE, else the first of source_places() that holds the source
    (GrblBuildError naming what is needed if none does)."""
    if os.environ.get(GRBL_SOURCE_ENV):
        return Path(os.environ[GRBL_SOURCE_ENV])
    places = source_places()
    found = next((place for place in places if _is_source(place)), None)
    if found is None:
        raise GrblBuildError(missing_source_text(places))
    return found


def missing_source_text(places: list[Path]) -> str:
    """What simavr://?firmware=grbl needs when no GRBL source was found."""
    looked = ", ".join(str(place) for place in places)
    return (f"simavr://?firmware=grbl builds stock GRBL 1.1h and found no source (looked in "
            f"{looked}): run from a galileo-cnc checkout (it holds third_party/grbl-1.1h), "
            f"or set {GRBL_SOURCE_ENV} to a grbl-1.1h folder holding its Makefile and grbl/ "
            f"({GRBL_SOURCE_URL}); building needs make, gcc-avr and avr-libc, and running "
            f"it the simavr harness (make -C firmware/harness)")


def build_dir() -> Path:
    """A checkout's firmware/build-grbl, else (installed with pip, run elsewhere) the
    user's cache."""
    if (REPO_ROOT / "firmware").is_dir():
        return BUILD_DIR
    for root in checkouts():
        return root / "firmware" / "build-grbl"
    cache = os.environ.get("XDG_CACHE_HOME") or str(Path.home() / ".cache")
    return Path(cache) / "galileo-cnc" / "build-grbl"


def source_digest(src: Path) -> str:
    h = hashlib.sha256()
    for path in sorted((src / "grbl").glob("*.[ch]")) + [src / "Makefile"]:
        h.update(path.name.encode() + b"\0" + path.read_bytes())
    return h.hexdigest()[:16]


def build_grbl(src: Path | None = None, out_dir: Path | None = None) -> Path:
    """The GRBL ELF, built from `src` unless the cached one came from the same source."""
    src = Path(src) if src else source_dir()
    out_dir = Path(out_dir) if out_dir else build_dir()
    if not _is_source(src):
        raise GrblBuildError(missing_source_text([src]))
    digest = source_digest(src)
    with build_lock(out_dir):       # another process may be building the same ELF
        return _build_unless_current(src, out_dir, digest)


def _build_unless_current(src: Path, out_dir: Path, digest: str) -> Path:
    elf = out_dir / ELF_NAME
    stamp = out_dir / "source.sha256"
    if elf.is_file() and (out_dir / "size.txt").is_file() and stamp.is_file() \
            and stamp.read_text().strip() == digest:
        return elf
    missing = missing_debian_packages(BUILD_PACKAGES)
    if missing:
        raise GrblBuildError(f"building GRBL needs make, and avr-gcc with avr-libc: install "
                             f"the Debian package{'s' if len(missing) > 1 else ''} "
                             f"{' '.join(missing)} (sudo apt install {' '.join(missing)})")
    with tempfile.TemporaryDirectory(prefix="galileo-grbl-") as tmp:
        work = Path(tmp) / "grbl-1.1h"
        shutil.copytree(src, work, ignore=shutil.ignore_patterns("build", "*.hex"))
        (work / "build").mkdir()
        result = subprocess.run(["make", "-C", str(work)], capture_output=True, text=True)
        if result.returncode != 0:
            raise GrblBuildError("GRBL's make failed:\n" + (result.stdout + result.stderr)[-3000:])
        out_dir.mkdir(parents=True, exist_ok=True)
        shutil.copyfile(work / "build" / "main.elf", elf)
        shutil.copyfile(work / "grbl.hex", out_dir / "grbl.hex")
        sizes = re.search(r"^\s*(\d+)\s+(\d+)\s+(\d+)\s", result.stdout, re.M)
        if sizes is None:
            raise GrblBuildError("no avr-size line in GRBL's make output")
        # avr-size's berkeley columns: text data bss (bytes)
        (out_dir / "size.txt").write_text(" ".join(sizes.groups()) + "\n")
    stamp.write_text(digest + "\n")
    return elf


def grbl_board(elf: Path | None = None, *, limits: tuple = (), trace: bool = True,
               extra_pins: tuple[int, ...] = (), extra_args: tuple[str, ...] = (),
               probe: ProbeSurface | None = None, **kwargs) -> SimulatedBoard:
    """A SimulatedBoard running GRBL. `limits`: (axis, trip in GRBL steps) pairs:
    the axis' limit switch closes while GRBL's position >= trip (GRBL homes
    toward +; the harness counts steps with dir high as +, GRBL as -). `probe`: a
    surface GRBL's probe pin (A5) touches, for G38.2."""
    endstops = [(axis, LIMIT_PINS["XYZ".index(axis)], -trip) for axis, trip in limits]
    probe_args = probe.harness_args() if probe is not None else ()
    return SimulatedBoard(elf or build_grbl(), trace=trace,
                          pins=TRACE_PINS + tuple(extra_pins), endstops=endstops,
                          extra_args=HARNESS_ARGS + probe_args + tuple(extra_args), **kwargs)


def grbl_step_trace(edges, dir_invert_mask: int = 0
                    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """GRBL's step and direction pin edges (board.trace()) as a step trace (tick,
    axis, dir), each step's direction in GRBL's own sense: a direction pin high is
    GRBL's negative direction, unless `$3` (its direction invert mask,
    `dir_invert_mask`) inverts that axis (stepper.c: direction_bits ^
    dir_port_invert_mask)."""
    tick, axis, direction = step_trace(edges, AXIS_PINS)
    sign = np.array([1 if dir_invert_mask >> a & 1 else -1 for a in range(3)], np.int8)
    return tick, axis, (direction * sign[axis]).astype(np.int8)
