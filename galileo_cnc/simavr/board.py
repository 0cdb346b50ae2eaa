"""Firmware in the loop: the project's simavr harness as a serial port.

`SimulatedBoard` starts `galileo-simavr` (built by `make -C firmware/harness`,
see docs/harness.md) on a firmware ELF. The board's UART0 appears as a
pseudo-terminal that pyserial opens like a real port; every edge of the traced
pins is recorded with its exact simulated cycle and comes back as numpy arrays.
`step_trace` turns those edges into the reference machine's step trace
(tick, axis, dir), so firmware and reference can be compared step for step.
"""

from __future__ import annotations

import os
import queue
import re
import shutil
import signal
import subprocess
import tempfile
import threading
from collections.abc import Iterable, Sequence
from pathlib import Path

import numpy as np

from galileo_cnc.config.hardware import F_CPU_HZ, TIMER1_PRESCALER
from galileo_cnc.errors import GalileoError
from galileo_cnc.machine.trace import Trace

#: The checkout this package runs from (a source tree or an editable install); after
#: `pip install .` it is site-packages' parent and holds no firmware.
REPO_ROOT = Path(__file__).resolve().parents[2]
HARNESS_NAME = "galileo-simavr"
HARNESS_RELATIVE = Path("firmware/harness/build") / HARNESS_NAME
FIRMWARE_RELATIVE = Path("firmware/build-uno/galileo.elf")
HARNESS_ENV = "GALILEO_SIMAVR"          # the harness binary
FIRMWARE_ENV = "GALILEO_FIRMWARE"       # the firmware ELF simavr:// runs

CYCLES_PER_TICK = TIMER1_PRESCALER  # one Timer1 tick in CPU cycles

# One record of the harness's --trace file.
TRACE_DTYPE = np.dtype([("cycle", "<u8"), ("pin", "u1"), ("level", "u1")])
# The pin of the record that marks a reset (SimulatedBoard.reset); read_trace's
# int8 pins give it as -1. Cycles count from power-up across resets.
RESET_MARK_PIN = np.int8(-1)

# (step pin, dir pin) of X, Y, Z on the Uno: the seed's pin map.
DEFAULT_AXIS_PINS: tuple[tuple[int, int], ...] = ((11, 10), (9, 8), (13, 12))
DEFAULT_TRACE_PINS = (8, 9, 10, 11, 12, 13)

# What each Debian package provides that the harness, its tests or the firmware
# build need: (package, file it installs or command it puts on PATH).
_DEBIAN_MARKERS: dict[str, str] = {
    "gcc": "cc",
    "make": "make",
    "libsimavr-dev": "/usr/include/simavr/sim_avr.h",
    "simavr": "simavr",
    "gcc-avr": "avr-gcc",
    "avr-libc": "/usr/lib/avr/include/avr/io.h",
    "arduino-core-avr": "/usr/share/arduino/hardware/arduino/avr/cores/arduino/Arduino.h",
    "arduino-mk": "/usr/share/arduino/Arduino.mk",
}
HARNESS_PACKAGES = ("gcc", "make", "libsimavr-dev")
TESTFW_PACKAGES = ("gcc-avr", "avr-libc")
FIRMWARE_PACKAGES = ("gcc-avr", "avr-libc", "arduino-core-avr", "arduino-mk")

# The byte firmware/galileo/stackpaint.cpp fills free SRAM with at reset.
STACK_PAINT_BYTE = 0xC5

_SUMMARY = re.compile(r"galileo-simavr: stop: (?P<reason>[^;]*); (?P<fields>.*)")
_STACK = re.compile(r"galileo-simavr: stack: (?P<fields>.*)")


class SimulatedBoardError(GalileoError):
    """The harness is missing, would not start, or stopped unexpectedly."""


def missing_debian_packages(packages: Iterable[str] = tuple(_DEBIAN_MARKERS)) -> list[str]:
    """The Debian packages among `packages` whose files or commands are absent."""
    missing = []
    for package in packages:
        marker = _DEBIAN_MARKERS[package]
        present = Path(marker).exists() if marker.startswith("/") else shutil.which(marker)
        if not present:
            missing.append(package)
    return missing


def checkouts() -> list[Path]:
    """galileo-cnc source trees to look in: the one this package runs from, then the
    current directory (a user who installed with pip and works in a checkout)."""
    found = []
    for root in (REPO_ROOT, Path.cwd()):
        root = root.resolve()
        if (root / "firmware" / "harness").is_dir() and root not in found:
            found.append(root)
    return found


def _executable(path: Path) -> bool:
    return path.is_file() and os.access(path, os.X_OK)


def harness_candidates() -> list[Path]:
    """Where the harness is looked for, in order: $GALILEO_SIMAVR, PATH, the checkouts."""
    if os.environ.get(HARNESS_ENV):
        return [Path(os.environ[HARNESS_ENV])]
    on_path = shutil.which(HARNESS_NAME)
    return ([Path(on_path)] if on_path else []) + [root / HARNESS_RELATIVE
                                                   for root in checkouts()]


def harness_path() -> Path:
    """The harness to run: the first candidate that exists (else the first looked at)."""
    candidates = harness_candidates()
    for path in candidates:
        if _executable(path):
            return path
    return candidates[0] if candidates else Path(HARNESS_NAME)


def harness_available() -> bool:
    return _executable(harness_path())


def harness_missing_message() -> str:
    looked = ", ".join(str(p) for p in harness_candidates()) or "no checkout found"
    return (f"the simavr harness {HARNESS_NAME} is not built (looked at ${HARNESS_ENV}, "
            f"PATH and the checkout: {looked}). In a galileo-cnc checkout run "
            f"`make -C firmware/harness` (Debian packages: libsimavr-dev, gcc), then run "
            f"from there, put firmware/harness/build on PATH, or set {HARNESS_ENV}")


def firmware_path() -> Path | None:
    """The firmware ELF `simavr://` runs: $GALILEO_FIRMWARE, else the checkout's build."""
    if os.environ.get(FIRMWARE_ENV):
        return Path(os.environ[FIRMWARE_ENV])
    for root in checkouts():
        if (root / FIRMWARE_RELATIVE).is_file():
            return root / FIRMWARE_RELATIVE
    return None


def firmware_missing_message() -> str:
    return (f"no firmware ELF (looked at ${FIRMWARE_ENV} and "
            f"{', '.join(str(r / FIRMWARE_RELATIVE) for r in checkouts()) or 'no checkout'}): "
            f"build it with `make -C firmware` in a galileo-cnc checkout (Debian packages: "
            f"arduino-mk, arduino-core-avr, gcc-avr, avr-libc), or pass ?elf=PATH")


def read_trace(path: str | os.PathLike) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(cycle int64, pin int8, level int8) from a --trace file; a record cut
    short by a flush still under way is left out."""
    raw = Path(path).read_bytes() if Path(path).exists() else b""
    whole = len(raw) - len(raw) % TRACE_DTYPE.itemsize
    records = np.frombuffer(raw[:whole], dtype=TRACE_DTYPE)
    return (records["cycle"].astype(np.int64), records["pin"].astype(np.int8),
            records["level"].astype(np.int8))


def reset_cycles(edges: tuple[np.ndarray, np.ndarray, np.ndarray]) -> np.ndarray:
    """The cycles (since power-up) at which the board was reset."""
    cycle, pin, _ = edges
    return np.asarray(cycle)[np.asarray(pin) == RESET_MARK_PIN]


def step_trace(edges: tuple[np.ndarray, np.ndarray, np.ndarray],
               pins: Sequence[tuple[int, int]] = DEFAULT_AXIS_PINS,
               cycles_per_tick: int = CYCLES_PER_TICK) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Step-pin rising edges as the reference machine's trace: (tick, axis, dir).

    `pins[axis]` is that axis' (step pin, dir pin). A step's direction is the
    level of its dir pin as last recorded before the step edge (+1 high, -1
    low; low until first recorded, as after reset), so a dir change written in
    the same instruction as the step counts. Steps sharing a tick are ordered
    X, Y, Z, as in the reference trace.
    """
    cycle, pin, level = (np.asarray(a) for a in edges)
    index = np.arange(len(cycle))
    ticks, axes, dirs = [], [], []
    for axis, (step_pin, dir_pin) in enumerate(pins):
        steps = index[(pin == step_pin) & (level == 1)]
        dir_at = index[pin == dir_pin]
        last = np.searchsorted(dir_at, steps) - 1
        dir_level = np.where(last >= 0, level[dir_at[np.maximum(last, 0)]] if len(dir_at) else 0, 0)
        ticks.append(cycle[steps].astype(np.int64) // cycles_per_tick)
        axes.append(np.full(len(steps), axis, dtype=np.int8))
        dirs.append(np.where(dir_level == 1, 1, -1).astype(np.int8))
    tick = np.concatenate(ticks) if ticks else np.zeros(0, np.int64)
    axis = np.concatenate(axes) if axes else np.zeros(0, np.int8)
    direction = np.concatenate(dirs) if dirs else np.zeros(0, np.int8)
    order = np.lexsort((axis, tick))
    return tick[order], axis[order], direction[order]


def runs_between_resets(edges: tuple[np.ndarray, np.ndarray, np.ndarray],
                        pins: Sequence[tuple[int, int]] = DEFAULT_AXIS_PINS,
                        cycles_per_tick: int = CYCLES_PER_TICK) -> list[Trace]:
    """The step pins' steps as reference traces, one per run of the firmware: the
    first from power-up, each next one from the reset before it (`reset_cycles`).
    A run's final_position is its net steps: where the head stood when it began is
    the caller's to say (the end-stops keep it across a reset, Z has none)."""
    tick, axis, direction = step_trace(edges, pins, cycles_per_tick)
    bounds = np.searchsorted(tick * cycles_per_tick, reset_cycles(edges)).tolist()
    runs = []
    for lo, hi in zip([0, *bounds], [*bounds, len(tick)]):
        t, a, d = tick[lo:hi], axis[lo:hi], direction[lo:hi]
        moved = tuple(int(d[a == k].sum()) for k in range(3))
        runs.append(Trace(t, a, d, moved, int(t[-1]) if len(t) else 0))
    return runs


class SimulatedBoard:
    """A firmware ELF running in the harness, its UART0 on a pseudo-terminal.

        with SimulatedBoard("firmware/build-uno/galileo_.elf") as board:
            port = serial.Serial(board.port, DEFAULT_BAUD, timeout=2)
            ...
        cycle, pin, level = board.trace()

    `endstops` takes ("X", 7, -100)-style tuples or "X:7:-100" strings (see
    docs/harness.md). `stack_paint` (a byte, e.g. STACK_PAINT_BYTE, for a
    firmware that paints its free SRAM at reset) measures the stack's
    high-water mark: `stack`, `stack_peak_bytes`, `stack_free_bytes` after
    stop(). Nothing is built here: run `make -C firmware/harness`.
    """

    def __init__(self, elf: str | os.PathLike, *, trace: bool = True,
                 pins: Iterable[int] | None = None,
                 endstops: Iterable[tuple[str, int, int] | str] = (),
                 max_seconds: float | None = None, realtime: bool = False,
                 freq_hz: int = F_CPU_HZ, extra_args: Sequence[str] = (),
                 binary: str | os.PathLike | None = None, start_timeout: float = 10.0,
                 stack_paint: int | None = None):
        self.elf = Path(elf)
        self.binary = Path(binary) if binary else harness_path()
        self.start_timeout = start_timeout
        self.realtime = realtime                # paced to wall time, as a board runs
        self._want_trace = trace
        # a board outlives no host: a killed test run leaves no simulation running
        self._args = ["--freq", str(freq_hz), "--exit-with-parent"]
        if pins is not None:
            self._args += ["--pins", ",".join(str(p) for p in pins)]
        for stop in endstops:
            spec = stop if isinstance(stop, str) else ":".join(str(part) for part in stop)
            self._args += ["--endstop", spec]
        if max_seconds is not None:
            self._args += ["--max-seconds", repr(float(max_seconds))]
        if realtime:
            self._args.append("--realtime")
        if stack_paint is not None:
            self._args += ["--stack-paint", f"0x{stack_paint:02x}"]
        self._args += list(extra_args)
        self._dir: Path | None = None
        self._process: subprocess.Popen | None = None
        self._lines: queue.Queue[str | None] = queue.Queue()
        self._reader: threading.Thread | None = None
        self._edges: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None
        self.port: str | None = None    # path for pyserial (a symlink to the slave)
        self.slave: str | None = None   # /dev/pts/N
        self.log = ""                   # the harness's stderr, after stop()
        self.summary: dict[str, str] = {}  # its exit summary, after stop()
        # Its "stack:" line as ints (addresses too), after stop() with stack_paint.
        self.stack: dict[str, int] = {}
        self.returncode: int | None = None
        self._frozen = False

    # -- lifetime -----------------------------------------------------------

    def __enter__(self) -> "SimulatedBoard":
        return self.start()

    def __exit__(self, *exc) -> None:
        self.close()

    def start(self) -> "SimulatedBoard":
        if self._process is not None:
            raise SimulatedBoardError("the simulated board is already started")
        if not _executable(Path(self.binary)):
            raise SimulatedBoardError(harness_missing_message())
        if not self.elf.is_file():
            raise SimulatedBoardError(f"firmware ELF not found: {self.elf}")
        self._dir = Path(tempfile.mkdtemp(prefix="galileo-simavr-"))
        link = self._dir / "ttyGALILEO"
        args = [str(self.binary), "--pty", str(link)]
        if self._want_trace:
            args += ["--trace", str(self._dir / "trace.bin")]
        args += self._args + [str(self.elf)]
        with open(self._dir / "harness.log", "wb") as log:
            # its own session: Ctrl-C at the console (SIGINT to the terminal's process
            # group) must stop the job, not kill the simulated board
            self._process = subprocess.Popen(args, stdin=subprocess.DEVNULL,
                                             stdout=subprocess.PIPE, stderr=log,
                                             start_new_session=True)
        self._reader = threading.Thread(target=self._read_stdout, daemon=True)
        self._reader.start()
        try:
            line = self._lines.get(timeout=self.start_timeout)
        except queue.Empty:
            self.close()
            raise SimulatedBoardError(
                f"harness gave no 'pty:' line within {self.start_timeout} s") from None
        if line is None or not line.startswith("pty: "):
            self.close()
            raise SimulatedBoardError(f"harness did not start: {self.log.strip() or line}")
        self.slave = line[len("pty: "):].strip()
        self.port = str(link)
        return self

    def _read_stdout(self) -> None:
        assert self._process is not None and self._process.stdout is not None
        for raw in self._process.stdout:
            self._lines.put(raw.decode(errors="replace"))
        self._lines.put(None)

    @property
    def running(self) -> bool:
        return self._process is not None and self._process.poll() is None

    def wait(self, timeout: float | None = None) -> int:
        """Waits for the harness to stop by itself (--max-seconds, a crash,
        sleep with interrupts off) and collects its results."""
        assert self._process is not None
        self._process.wait(timeout)
        return self._finish()

    def freeze(self) -> None:
        """Stops simulated time (SIGSTOP to the harness): the firmware stays exactly
        where it is, in the middle of a move if it moves, and what the host writes
        waits in the pty. A test makes "the host acts while the board is still busy"
        happen at a chosen moment this way, not by a race with the wall clock."""
        if self.running and not self._frozen:
            self._process.send_signal(signal.SIGSTOP)
            self._frozen = True

    def thaw(self) -> None:
        """Simulated time goes on from where `freeze` stopped it."""
        if self._process is not None and self._frozen:
            self._process.send_signal(signal.SIGCONT)
            self._frozen = False

    def reset(self) -> None:
        """Presses the reset button (SIGUSR1 to the harness), as an Uno's auto-reset
        does when a port opens: the firmware starts again from power-up, the head
        stays where it is and the end-stops keep counting from there. The trace
        goes on, with a mark at the reset (`reset_cycles`)."""
        if self.running:
            self.thaw()
            self._process.send_signal(signal.SIGUSR1)

    def stop(self, timeout: float = 10.0) -> int:
        """SIGTERM, then the exit code; the trace and log stay readable."""
        if self._process is None:
            return self.returncode if self.returncode is not None else 0
        self.thaw()                     # a stopped process would not see SIGTERM
        if self._process.poll() is None:
            self._process.send_signal(signal.SIGTERM)
            try:
                self._process.wait(timeout)
            except subprocess.TimeoutExpired:
                self._process.kill()
                self._process.wait()
        return self._finish()

    def _finish(self) -> int:
        assert self._process is not None and self._dir is not None
        self.returncode = self._process.returncode
        if self._reader is not None:
            self._reader.join(timeout=5)  # it ends at the pipe's EOF
        if self._process.stdout:
            self._process.stdout.close()
        self.log = (self._dir / "harness.log").read_text(errors="replace")
        match = _SUMMARY.search(self.log)
        if match:
            self.summary = {"reason": match["reason"]}
            self.summary.update(re.findall(r"(\w+)=(\S+)", match["fields"]))
        match = _STACK.search(self.log)
        if match:
            self.stack = {key: int(value, 0) for key, value in
                          re.findall(r"(\w+)=(0x[0-9a-f]+|\d+)(?=\s|$)", match["fields"])}
        if self._want_trace:
            self._edges = read_trace(self._dir / "trace.bin")
        self._process = None
        return self.returncode

    def close(self) -> None:
        self.stop()
        if self._dir is not None:
            shutil.rmtree(self._dir, ignore_errors=True)
            self._dir = None

    # -- results ------------------------------------------------------------

    @property
    def stack_peak_bytes(self) -> int | None:
        """The deepest the stack wrote, in bytes below RAMEND + 1 (painting);
        None unless started with stack_paint and stopped."""
        return self.stack.get("peak")

    @property
    def stack_free_bytes(self) -> int | None:
        """SRAM never touched between the static data's end and the stack's
        deepest write; None unless started with stack_paint and stopped."""
        return self.stack.get("free")

    @property
    def records_steps(self) -> bool:
        """Started with a trace: its pins' edges can be read (complete once stopped)."""
        return self._want_trace

    def trace(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(cycle int64, pin int8, level int8) of every traced edge so far."""
        if self._edges is not None:
            return self._edges
        if not self._want_trace or self._dir is None:
            raise SimulatedBoardError("this board was started without a trace")
        return read_trace(self._dir / "trace.bin")

    def step_trace(self, pins: Sequence[tuple[int, int]] = DEFAULT_AXIS_PINS):
        return step_trace(self.trace(), pins)
