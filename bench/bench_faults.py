"""Streaming over a noisy cable: seeded fault campaigns on sim:// and on the firmware in simavr.

Every session streams one planned job through `NoisyPort`, a pass-through around the
real port that corrupts (one bit flipped), drops, duplicates or delays bytes in both
directions at a rate per byte, loses the n-th reply line, or resets the machine after
the n-th line. Each session ends as one of:

    finished  the job completed and the machine stepped the fault-free trace
    stopped   it stopped with a message; then resumed over a clean cable to the
              fault-free drawing (`resumed`), or resuming was refused with a message
              (`refused`: a reset machine lost its position). Reset sessions run homed
              (`plot --home`), so a reset is resumed by homing again; in simavr the
              harness presses the board's reset (SimulatedBoard.reset)
    hang      no end within the session's time limit
    wrong     it completed (or resumed) with steps other than the fault-free trace:
              a silent loss, a repeated move, a move that should not have run
    crash     an exception that is not a GalileoError (a traceback)

The fault-free trace on sim:// (instant clock) is the reference's to the tick; on the
firmware, whose timing depends on the pauses faults cause, it is the same steps in the
same order and the same final position. A resumed job retraces part of a command and
travels back to it pen up, so it is judged by the points it inked and where it ends.
A reset restarts sim://'s trace (simavr's goes on, with a mark): the points inked
before it and after it are taken in the machine's power-up frame, and their union
must be the homed fault-free run's. Z has no end-stop, so after a reset the user of
the bench turns the pen back to its Z origin, as the docs ask of a real user.

    python3 bench/bench_faults.py                     # 1,000 on sim://, 1,000 on simavr
    python3 bench/bench_faults.py --sim 200 --simavr 0 --seed 7
    python3 bench/bench_faults.py --sim 0 --simavr 600 --part 1/2   # half of one campaign;
    python3 bench/bench_faults.py --sim 0 --simavr 600 --part 2/2   # the other on a 2nd core
    python3 bench/bench_faults.py --sim 0 --simavr 70 --only reset    # its 11 resets
    python3 bench/bench_faults.py --sim 0 --simavr 600 --part 1/2 --start 120  # go on

Reproducible for a seed: the sessions (kind, rate, which reply is lost, when the reset
comes) and each direction's fault draws. Not reproducible: which bytes the host sends
depends on its timeouts (how many status queries, when a stall is declared) and so on
the machine's load, so two runs of one seed can differ in the bytes faults hit; the
outcome counts vary a little between runs, not the targets.
"""

from __future__ import annotations

import argparse
import random
import sys
import threading
import time
import traceback
from collections import Counter
from dataclasses import dataclass
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO / "tests"))

from galileo_cnc.errors import GalileoError  # noqa: E402
from galileo_cnc.job import Home, PenUp  # noqa: E402
from galileo_cnc.machine import simulate  # noqa: E402
from galileo_cnc.plan.offsets import proposed_offset  # noqa: E402
from galileo_cnc.plan.planner import plan_program  # noqa: E402
from galileo_cnc.readers import read_file  # noqa: E402
from galileo_cnc.sim.simulator import forget_named_machines  # noqa: E402
from galileo_cnc.stream.homing import home  # noqa: E402
from galileo_cnc.stream.journal import Journal  # noqa: E402
from galileo_cnc.stream.resume import resume_job  # noqa: E402
from galileo_cnc.stream.streamer import JobStreamer  # noqa: E402
from galileo_cnc.transport.link import MachineLink  # noqa: E402
from galileo_cnc.transport.port import open_port  # noqa: E402

RATES = (0.001, 0.01, 0.05)
KINDS = ("corrupt", "drop", "duplicate", "delay")
OUTCOMES = ("finished", "resumed", "refused", "hang", "wrong", "crash")
SAMPLE = REPO / "samples" / "led-blinker.gbr"


@dataclass(frozen=True)
class Fault:
    """What one session does to the cable."""

    kinds: tuple[str, ...] = ()     # per-byte faults, both directions
    rate: float = 0.0
    lose_reply: int = 0             # the n-th line reply (ok, error, rs) never arrives
    reset_after: int = 0            # the machine is reset after the n-th line written

    def label(self) -> str:
        if self.lose_reply:
            return "lost reply"
        if self.reset_after:
            return "reset mid-job"
        what = "+".join(self.kinds) if len(self.kinds) == 1 else "mixed"
        return f"{what} {self.rate * 100:g} %"


class NoisyPort:
    """A pyserial port passed through with `fault`, drawn from seeded generators: one
    per direction, so that the n-th byte each way meets the same fault whatever the
    threads' interleaving (which bytes go out still depends on timeouts: see main)."""

    def __init__(self, port, fault: Fault, seed: int, reset=None):
        self.port, self.fault, self._reset = port, fault, reset
        self.rng_out, self.rng_in = random.Random(seed), random.Random(seed ^ 0x5A5A5A5A)
        self.lines_written = self.replies_read = 0
        self.enabled = False            # after the greeting: the session under test

    def _noise(self, data: bytes, rng: random.Random) -> bytes:
        if not self.enabled or not self.fault.rate:
            return data
        out = bytearray()
        for byte in data:
            if rng.random() >= self.fault.rate:
                out.append(byte)
                continue
            kind = rng.choice(self.fault.kinds)
            if kind == "corrupt":
                out.append(byte ^ (1 << rng.randrange(8)))
            elif kind == "duplicate":
                out += bytes((byte, byte))
            elif kind == "delay":
                time.sleep(rng.uniform(0.0, 0.05))
                out.append(byte)
            # drop: nothing
        return bytes(out)

    def write(self, data: bytes) -> int:
        if self.enabled and data.endswith(b"\n"):
            self.lines_written += 1
            if self.lines_written == self.fault.reset_after and self._reset is not None:
                self._reset()
        self.port.write(self._noise(data, self.rng_out))
        return len(data)

    def readline(self) -> bytes:
        line = self.port.readline()
        if self.enabled and line.endswith(b"\n") and line.startswith((b"ok", b"rs", b"error")):
            self.replies_read += 1
            if self.replies_read == self.fault.lose_reply:
                return b""
        return self._noise(line, self.rng_in)

    def close(self) -> None:
        self.port.close()

    def __getattr__(self, name):
        return getattr(self.port, name)


# ---- the machines -------------------------------------------------------------------------
class SimTarget:
    name = "sim://"
    hang_s = 60.0
    # the instant machine answers inside the write: a reply missing for 50 ms is lost
    # (a late one only costs a status query). At 0.3 s a session took ~3 s, 1,000 an hour.
    timeouts = dict(status_retry_s=0.02, reply_s=0.1, stall_s=0.05)

    def __init__(self):
        self._n = 0
        self.before_reset = None        # the trace a reset ended
        self.resumed_from = (0, 0, 0)

    def session(self, homed=False):
        """(url, open a port, the fault-free trace of what ran, reset, close) for one
        session; `homed`: the machine has end-stops to home on (sim:// always has)."""
        self._n += 1
        url = f"sim://bench{self._n}?speed=0"
        from galileo_cnc.sim.simulator import named_machine
        self.before_reset = None

        def trace():
            return named_machine(f"bench{self._n}").trace()

        def reset():
            self.before_reset = named_machine(f"bench{self._n}").reset()
        return url, (lambda: open_port(url, timeout=0.1)), trace, reset, forget_named_machines

    def pen_to_z_origin(self) -> None:
        """The user after a reset: the pen turned back to its Z origin (Z has no end
        stop)."""
        from galileo_cnc.sim.simulator import named_machine
        self.resumed_from = (0, 0, 0)
        if self.before_reset is None:
            return
        machine = named_machine(f"bench{self._n}")
        x, y, _ = machine.physical_position()
        machine.move_by_hand((x, y, 0))
        self.resumed_from = (x, y, 0)

    def drawing(self, trace):
        """(the points inked, where the head ended) in the power-up frame: after a
        reset, the run before it and the run after it from where the user left it."""
        from inked import inked_points
        drawn = inked_points(trace, start=self.resumed_from)
        if self.before_reset is not None:
            drawn |= inked_points(self.before_reset)
        return drawn, end_of(trace, self.resumed_from)

    @staticmethod
    def same(trace, ref) -> bool:
        return trace.same_steps(ref)


class SimavrTarget:
    name = "simavr"
    hang_s = 180.0
    timeouts = dict(status_retry_s=0.3, reply_s=1.0, stall_s=1.0)
    # the switches where the reference machine has them (MachineConfig's sim_*)
    ENDSTOPS = ("X:7:-400", "Y:6:-400")

    def __init__(self):
        from firmware_support import ELF, build_firmware, build_harness
        build_firmware()
        build_harness()
        self.elf = ELF
        self._runs = []                 # the last session's steps, a Trace per reset

    def session(self, homed=False):
        from galileo_cnc.simavr.board import SimulatedBoard, runs_between_resets
        board = SimulatedBoard(self.elf, endstops=self.ENDSTOPS if homed else ()).start()

        def trace():
            # stopped first: the harness flushes its pin record only every 100 ms, so
            # one read while it runs can miss the last steps (40 of 100 "wrong" so).
            # The whole session's steps, or after a reset the run before it (`drawing`
            # takes every run)
            board.stop()
            self._runs = runs_between_resets(board.trace())
            return self._runs[0]
        return (board.port, (lambda: open_port(board.port, timeout=0.1)), trace, board.reset,
                board.close)

    def pen_to_z_origin(self) -> None:
        """Nothing to do while it runs: `drawing` takes the pen as turned back to its
        Z origin at the reset (the harness cannot move the head by hand)."""

    def drawing(self, trace):
        """(the points inked, where the head ended) in the power-up frame, from the
        runs of the last trace() (`trace` is its first): the steps before a reset,
        then each next run from where the head stood then with the pen at its Z origin."""
        from inked import inked_points
        first, *after = self._runs
        drawn, here = inked_points(first), end_of(first)
        for run in after:               # each from where the head stood, pen at Z origin
            start = (here[0], here[1], 0)
            drawn |= inked_points(run, start=start)
            here = end_of(run, start)
        return drawn, here

    @staticmethod
    def same(trace, ref) -> bool:
        import numpy as np
        return (np.array_equal(trace.axis, ref.axis) and np.array_equal(trace.dir, ref.dir))


def end_of(trace, start=(0, 0, 0)) -> tuple[int, int, int]:
    """Where the steps of `trace` leave the head that stood at `start`."""
    return tuple(int(s + moved) for s, moved in zip(start, trace.displacement()))


# ---- one session --------------------------------------------------------------------------
def _attach(target, port, url):
    link = MachineLink.attach(port, url)
    link.status_retry_s = target.timeouts["status_retry_s"]
    link.reply_s = target.timeouts["reply_s"]
    return link


def _run(target, fn, log):
    """fn() in a thread, bounded by the target's hang limit; (done, value or exception)."""
    box = {}

    def body():
        try:
            box["value"] = fn()
        except BaseException as exc:   # noqa: BLE001  classified by the caller
            box["error"] = exc
    thread = threading.Thread(target=body, daemon=True)
    thread.start()
    thread.join(target.hang_s)
    if thread.is_alive():
        return False, None
    return True, box.get("error", box.get("value"))


def session(target, job, program, fault: Fault, seed: int, tmp: Path, log=None) -> str:
    from inked import inked_points
    homed = bool(fault.reset_after)     # a reset is resumable only in the homed frame
    url, opener, trace_of, reset, close = target.session(homed)
    journal = Journal(tmp / f"journal-{seed}.json")
    journal.path.unlink(missing_ok=True)
    try:
        port = NoisyPort(opener(), fault, seed, reset)
        link = _attach(target, port, url)
        if homed:
            home(link)                  # as `plot --home`, before the faults begin
        port.enabled = True
        streamer = JobStreamer(link, job, program, journal=journal, homed=homed)
        streamer.stall_s = target.timeouts["stall_s"]
        messages = []
        link.on_message = messages.append
        done, value = _run(target, lambda: streamer.run(), log)
        if not done:
            return "hang"
        link.close()
        if log:
            log(f"{fault.label()} seed {seed}: {value!r}; {len(messages)} messages")
        ref = simulate(([PenUp(), Home()] if homed else []) + job.commands)
        if isinstance(value, BaseException) and not isinstance(value, GalileoError):
            if log:
                log("".join(traceback.format_exception(value)))
            return "crash"
        if not isinstance(value, BaseException):
            if value.completed:
                return "finished" if target.same(trace_of(), ref) else "wrong"
            return "crash"                          # nobody asked it to stop
        # stopped with a message: resume over a clean cable where it is possible
        if reset is None and fault.reset_after:
            return "refused"
        target.pen_to_z_origin()
        link = _attach(target, opener(), url)
        done, resumed = _run(target, lambda: resume_job(link, journal), log)
        link.close()
        if not done:
            return "hang"
        if log:
            log(f"resume: {resumed!r}")
        if isinstance(resumed, GalileoError):
            return "refused" if fault.reset_after else "wrong"   # lost a position it knew
        if isinstance(resumed, BaseException) or not resumed.completed:
            return "crash"
        drawn, end = target.drawing(trace_of())
        same = drawn == inked_points(ref) and end == end_of(ref)
        return "resumed" if same else "wrong"
    finally:
        close()


def plan(count: int, seed: int, replies: int) -> list[tuple[Fault, int]]:
    """`count` seeded sessions: a lost reply at every position, resets mid-job, the rest
    byte faults at each rate, one kind or all of them."""
    rng = random.Random(seed)
    sessions = [(Fault(lose_reply=k), rng.randrange(1 << 30)) for k in range(1, replies + 1)]
    sessions += [(Fault(reset_after=k), rng.randrange(1 << 30))
                 for k in range(2, replies, max(1, replies // 10))]
    kinds = [(k,) for k in KINDS] + [KINDS]
    noisy = [(Fault(kinds[i % len(kinds)], RATES[(i // len(kinds)) % len(RATES)]),
              rng.randrange(1 << 30)) for i in range(max(count - len(sessions), count))]
    if count >= len(sessions):          # every position, then byte faults
        return sessions + noisy[:count - len(sessions)]
    mixed = sessions + noisy            # a sample: some of each
    rng.shuffle(mixed)
    return mixed[:count]


def campaign(target, count: int, seed: int, tmp: Path, progress=True,
             partial: Path | None = None, part: tuple[int, int] = (1, 1),
             only: str | None = None, start: int = 0) -> Counter:
    """The seeded campaign of `count` sessions, or its part k of n (every n-th session
    from the k-th), so that n processes together run exactly the one campaign; `only`
    ("lost", "reset" or "bytes") keeps that kind of its sessions; `start` skips the
    first sessions of what is left (those a stopped run had done)."""
    program = read_file(SAMPLE)
    job = plan_program(program, None, proposed_offset(program))
    table: Counter = Counter()
    failures = []
    began = time.monotonic()
    k, n_parts = part
    sessions = plan(count, seed, len(job) + 2)[k - 1::n_parts]
    if only:
        sessions = [(f, s) for f, s in sessions if _kind(f) == only]
    count = len(sessions)
    for n, (fault, s) in enumerate(sessions[start:], start):
        outcome = session(target, job, program, fault, s, tmp)
        table[(fault.label(), outcome)] += 1
        if outcome in ("hang", "wrong", "crash"):
            failures.append(f"{target.name} {fault} seed {s}: {outcome}")
        if progress and (n + 1) % 50 == 0:
            print(f"  {target.name}: {n + 1}/{count} sessions, "
                  f"{time.monotonic() - began:.0f} s", file=sys.stderr, flush=True)
        if partial is not None:         # a long run (hours on simavr) keeps what it has
            partial.write_text(table_text(f"{target.name}: sessions {start + 1}..{n + 1} "
                                          f"of {count}, "
                                          f"seed {seed}, {time.monotonic() - began:.0f} s",
                                          table) + "".join(f"{f}\n" for f in failures))
    for line in failures:
        print(line)
    return table


def table_text(name: str, table: Counter) -> str:
    labels = sorted({label for label, _ in table})
    lines = [f"\n{name}", f"| faults | sessions | {' | '.join(OUTCOMES)} |",
             "| --- " * (len(OUTCOMES) + 2) + "|"]
    totals = Counter()
    for label in labels:
        row = [table[(label, o)] for o in OUTCOMES]
        totals.update({o: v for o, v in zip(OUTCOMES, row)})
        lines.append(f"| {label} | {sum(row)} | {' | '.join(map(str, row))} |")
    lines.append(f"| all | {sum(totals.values())} | "
                 f"{' | '.join(str(totals[o]) for o in OUTCOMES)} |")
    return "\n".join(lines) + "\n"


def print_table(name: str, table: Counter) -> None:
    print(table_text(name, table), end="")


def _kind(fault: Fault) -> str:
    return "lost" if fault.lose_reply else "reset" if fault.reset_after else "bytes"


def _part_option(text: str) -> tuple[int, int]:
    k, _, n = text.partition("/")
    try:
        k, n = int(k), int(n)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected K/N such as 1/2, got {text!r}") from None
    if not 1 <= k <= n:
        raise argparse.ArgumentTypeError(f"part {text}: K must be between 1 and N")
    return k, n


def main(argv=None) -> int:
    import tempfile
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--sim", type=int, default=1000, help="sessions on sim://")
    parser.add_argument("--simavr", type=int, default=1000, help="sessions on simavr")
    parser.add_argument("--seed", type=int, default=13)
    parser.add_argument("--partial", type=Path,
                        help="rewrite this file with the table so far after each session")
    parser.add_argument("--part", type=_part_option, default=(1, 1), metavar="K/N",
                        help="run only part K of N of the campaign (for N processes)")
    parser.add_argument("--only", choices=("lost", "reset", "bytes"),
                        help="run only the campaign's sessions of that kind")
    parser.add_argument("--start", type=int, default=0, metavar="N",
                        help="skip the first N sessions (a stopped run's, see --partial)")
    args = parser.parse_args(argv)
    bad = 0
    with tempfile.TemporaryDirectory() as tmp:
        for count, make in ((args.sim, SimTarget), (args.simavr, SimavrTarget)):
            if count <= 0:
                continue
            target = make()
            began = time.monotonic()
            table = campaign(target, count, args.seed, Path(tmp), partial=args.partial,
                             part=args.part, only=args.only, start=args.start)
            share = ("" if args.part == (1, 1) else f" (part {args.part[0]}/{args.part[1]})") + (
                f", only {args.only}" if args.only else "")
            print_table(f"{target.name}: {sum(table.values())} of {count} sessions{share}, "
                        f"seed {args.seed}, from session {args.start + 1}, "
                        f"{time.monotonic() - began:.0f} s", table)
            bad += sum(v for (_, o), v in table.items() if o in ("hang", "wrong", "crash"))
    return 1 if bad else 0


if __name__ == "__main__":
    raise SystemExit(main())
