"""Shared by the firmware tests: build once, skip or fail on missing packages,
and stream a job to the firmware running in the simavr harness.

Outside CI a missing Debian package skips the firmware tests with its name;
under CI=true it fails them (tests must not pass by skipping there).
"""

from __future__ import annotations

import os
import re
import subprocess
import time
from pathlib import Path

import pytest

from galileo_cnc import protocol as P
from galileo_cnc.simavr import board as simavr
from galileo_cnc.simavr.build_lock import build_lock

REPO = Path(__file__).resolve().parents[1]
FIRMWARE_DIR = REPO / "firmware"
ELF = FIRMWARE_DIR / "build-uno" / "galileo.elf"
BAUD = 115200

UNO_FLASH_BYTES = 32 * 1024 - 512   # minus the optiboot boot loader
UNO_RAM_BYTES = 2048
STACK_MARGIN_BYTES = 512            # left free for the stack (measured peak 234 B: test_firmware_build)


def require_packages(packages) -> None:
    missing = simavr.missing_debian_packages(packages)
    if missing:
        message = f"missing Debian packages: {' '.join(missing)}"
        if os.environ.get("CI"):
            pytest.fail(message)
        pytest.skip(message)


_built: dict = {}


def build_firmware() -> dict:
    """`make -C firmware` once per session; returns the parsed avr-size figures."""
    require_packages(simavr.FIRMWARE_PACKAGES)
    if not _built:
        with build_lock(FIRMWARE_DIR):      # pytest-xdist: another worker may be building
            result = subprocess.run(["make", "-C", str(FIRMWARE_DIR)], capture_output=True,
                                    text=True)
        _built["output"] = result.stdout + result.stderr
        _built["returncode"] = result.returncode
        flash = re.search(r"Program:\s+(\d+) bytes", result.stdout)
        ram = re.search(r"Data:\s+(\d+) bytes", result.stdout)
        _built["flash_bytes"] = int(flash.group(1)) if flash else None
        _built["ram_bytes"] = int(ram.group(1)) if ram else None
    assert _built["returncode"] == 0, _built["output"][-3000:]
    return _built


def build_firmware_for(config, where: Path) -> Path:
    """The firmware built for another profile than the defaults: firmware/ copied to
    `where` with config.h generated from `config`, as `make -C firmware headers
    PROFILE_TOML=...` would write it for a user's machine. Returns its ELF."""
    import shutil
    from galileo_cnc.firmware_headers import config_header
    require_packages(simavr.FIRMWARE_PACKAGES)
    tree = where / "firmware"
    shutil.copytree(FIRMWARE_DIR, tree, ignore=shutil.ignore_patterns("build-*", "harness"))
    (tree / "galileo" / "config.h").write_text(config_header(config, "a test's profile"))
    result = subprocess.run(["make", "-C", str(tree)], capture_output=True, text=True)
    assert result.returncode == 0, (result.stdout + result.stderr)[-3000:]
    return tree / "build-uno" / "galileo.elf"


_harness_built: list = []


def build_harness() -> None:
    """`make -C firmware/harness harness` once per session: make rebuilds what changed,
    so a checkout's older harness is never the one tested."""
    require_packages(simavr.HARNESS_PACKAGES)
    if not _harness_built:
        with build_lock(FIRMWARE_DIR / "harness"):
            result = subprocess.run(["make", "-C", str(FIRMWARE_DIR / "harness"), "harness"],
                                    capture_output=True, text=True)
        assert result.returncode == 0, result.stdout + result.stderr
        _harness_built.append(True)


class FirmwareLink:
    """A pyserial link to the firmware that streams framed lines with character
    counting against the advertised RX buffer (docs/protocol.md)."""

    def __init__(self, port: str, timeout: float = 60.0):
        import serial
        self.port = serial.Serial(port, BAUD, timeout=timeout)
        self.banner = P.parse_reply(self.port.readline())
        assert self.banner.kind == "banner", self.banner
        P.check_banner(self.banner.banner)
        self.seq = 0
        self.unsolicited: list[P.Reply] = []

    def close(self) -> None:
        self.port.close()

    def read_reply(self) -> P.Reply:
        raw = self.port.readline()
        assert raw.endswith(b"\n"), f"no reply (got {raw!r})"
        return P.parse_reply(raw)

    def _line_reply(self) -> P.Reply:
        while True:
            reply = self.read_reply()
            if reply.kind in ("ok", "error", "rs"):
                return reply
            self.unsolicited.append(reply)

    def send_raw(self, raw: bytes) -> P.Reply:
        self.port.write(raw)
        return self._line_reply()

    def send(self, cmd) -> P.Reply:
        line = P.encode_command(cmd, self.seq)
        self.seq = P.next_seq(self.seq)
        reply = self.send_raw(line)
        if reply.kind == "error" and reply.seq is not None:
            self.seq = reply.seq        # a refused line is not counted: expected again
        return reply

    def stream(self, commands) -> list[P.Reply]:
        """Send every command, keeping the RX buffer full; one reply each, in order."""
        lines = []
        for cmd in commands:
            lines.append(P.encode_command(cmd, self.seq))
            self.seq = P.next_seq(self.seq)
        replies, in_flight, i = [], [], 0
        while i < len(lines) or in_flight:
            while i < len(lines) and sum(map(len, in_flight)) + len(lines[i]) <= P.RX_BUFFER_BYTES:
                self.port.write(lines[i])
                in_flight.append(lines[i])
                i += 1
            replies.append(self._line_reply())
            in_flight.pop(0)
        return replies

    def status(self) -> P.Status:
        self.port.write(P.RT_STATUS)
        while True:
            reply = self.read_reply()
            if reply.kind == "status":
                return reply.status
            self.unsolicited.append(reply)

    def wait_idle(self, timeout_s: float = 300.0) -> P.Status:
        deadline = time.monotonic() + timeout_s
        while time.monotonic() < deadline:
            status = self.status()
            if status.state in ("idle", "alarm") and status.queue_blocks == 0:
                return status
            time.sleep(0.02)
        raise AssertionError(f"machine still busy after {timeout_s} s: {status}")


def status_when(link: "FirmwareLink", predicate, timeout_s: float = 5.0,
                poll_s: float = 0.002) -> P.Status:
    """Poll the real-time status until `predicate(status)` holds."""
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        status = link.status()
        if predicate(status):
            return status
        time.sleep(poll_s)
    raise AssertionError(f"status never matched: {status}")


def framed(body: bytes) -> bytes:
    """A line with the right check but whatever body the test wants (valid or not)."""
    return P.checked(body)


def check_bad_input_replies(link: "FirmwareLink", idle_timeout_s: float) -> None:
    """Bad input over the wire gets the documented reply and the next line works.

    One sequence for every machine behind the protocol: the firmware in simavr
    and sim:// must answer it identically.
    """
    from galileo_cnc.job import Jog, LineTo, SetFeed

    assert link.send(P.QueryStatus()).kind == "ok"               # N0
    assert link.send_raw(b"\x01\xfegarbage#$%\n") == P.Reply("rs", 1)
    assert link.send_raw(b"N1 S*0000\n") == P.Reply("rs", 1)     # bad checksum
    good = framed(b"N1 S")
    assert link.send_raw(good[:-6] + b"#" + good[-5:]) == P.Reply("rs", 1)  # wrong parity
    assert link.send_raw(framed(b"N7 S")) == P.Reply("rs", 1)    # wrong sequence
    r = link.send_raw(b"N1 L " + b"1" * 70 + b"\n")
    assert (r.kind, r.code) == ("error", 2)                      # over-long
    assert link.send_raw(framed(b"N1 ZAP 3")).code == 3          # unknown command
    # a refused line is not counted: N1 is expected again, N2 is out of sequence
    assert link.send_raw(framed(b"N2 L 1")) == P.Reply("rs", 1)
    assert link.send_raw(framed(b"N1 L 1")).code == 4            # too few arguments
    link.seq = 1
    r = link.send(LineTo(-5, 0))                                 # past the travel
    assert (r.kind, r.code, r.seq) == ("error", 5, 1)
    assert "X would reach -5, below 0" in r.text
    assert link.status().last_seq == 0                           # the refusal shows
    assert link.send(SetFeed(50_000)).code == 6
    r = link.send(Jog(10, 20, 0))
    assert r == P.Reply("ok", 1)
    status = link.wait_idle(idle_timeout_s)
    assert (status.x_steps, status.y_steps, status.last_seq) == (10, 20, 1)
