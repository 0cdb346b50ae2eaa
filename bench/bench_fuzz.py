"""Fuzz campaign for the readers: seeded mutants of real files, each read in a child.

    python3 bench/bench_fuzz.py                      # 10,000 mutants from seed 0, all CPUs
    python3 bench/bench_fuzz.py --mutants 500 --first 20000 --jobs 2
    python3 bench/bench_fuzz.py --show SEED          # one mutant here, with its traceback
    python3 bench/bench_fuzz.py --write SEED DIR     # write one mutant's file to DIR
    python3 bench/bench_fuzz.py --show SEED --ci     # a mutant of the CI sample (test_fuzz.py)
    python3 bench/bench_fuzz.py --formats drill      # 10,000 Excellon drill-file mutants

The mutants come from tests/readers/mutants.py (flips, truncation, splices, huge
numbers, deep nesting, huge repeats, the oddities real files hold, binary bytes), over
small files of the shared Gerber and DXF corpus, its Excellon drill files and G-code
written from them. Each mutant is written to a temporary file and read with
`galileo_cnc.readers.read_file` (a drill mutant with `read_drill`) in a forked child (everything imported once, in the parent) whose address space is
limited to what it had plus --memory-mb, and which is killed after --timeout seconds.

Outcomes:
- ok: read, and every coordinate within the reader's bound (no silent wrap-around);
- positioned: a GalileoError that names file:line (line >= 1);
- traceback: anything else (another exception, an error without a position, a numpy
  RuntimeWarning, a coordinate out of bounds in a "successful" read, a crash);
- hang: more than --timeout seconds of CPU time (RLIMIT_CPU, so other load on the
  machine does not count), or blocked for six times that in wall time;
- memory: MemoryError, or a peak resident size above --memory-mb.

The table counts outcomes per mutation kind and per format; every failure is listed
with its seed. Exit status 1 if there is any failure.
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import signal
import sys
import tempfile
import time
import traceback
import warnings
from collections import Counter, defaultdict
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))
sys.path.insert(0, str(REPO / "tests" / "readers"))

import mutants  # noqa: E402  (tests/readers/mutants.py: the seeded generator)

OUTCOMES = ("ok", "positioned", "traceback", "hang", "memory")
WALL_FACTOR = 6  # a child blocked (not computing) is killed after this many timeouts
FAILURES = ("traceback", "hang", "memory")
# What a successful read may hold: each reader's own coordinate bound.
BOUNDS_NM = {"gerber": 10**10, "gcode": 10**12, "dxf": 10**15, "drill": 10**10}


# --------------------------------------------------------------------------- child

def _status_kb(field: str) -> int:
    try:
        with open("/proc/self/status") as handle:
            for line in handle:
                if line.startswith(field + ":"):
                    return int(line.split()[1])
    except OSError:
        pass
    return 0


def _reset_peak() -> bool:
    try:
        with open("/proc/self/clear_refs", "w") as handle:
            handle.write("5")  # resets VmHWM to the current resident size
        return True
    except OSError:
        return False


def drill_coordinates(drill) -> list[int]:
    """Every coordinate a DrillFile holds (holes, slot ends, arc centres), in nm."""
    values = [v for h in drill.holes for v in (h.x_nm, h.y_nm)]
    values += [v for s in drill.slots for v in (s.x0_nm, s.y0_nm, s.x1_nm, s.y1_nm, s.cx_nm, s.cy_nm)]
    return values


def _read(path: str, fmt: str) -> tuple[int, int, str]:
    """(largest coordinate in nm, items read, the format read) of `path`."""
    import numpy as np

    from galileo_cnc.program.ops import I, J, X, Y
    from galileo_cnc.readers import read_drill, read_file

    if fmt == "drill":
        drill = read_drill(path)
        values = drill_coordinates(drill)
        return max(map(abs, values), default=0), len(drill.holes) + len(drill.slots), "drill"
    program = read_file(path)
    table = program.table
    biggest = int(np.abs(table[:, [X, Y, I, J]]).max()) if len(table) else 0
    return biggest, len(table), program.format


def classify(path: str, fmt_bounds=BOUNDS_NM, fmt: str = "") -> tuple[str, str]:
    """Read `path` with read_file (read_drill for a drill mutant): (outcome, detail)."""
    from galileo_cnc.errors import GalileoError

    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        try:
            biggest, size, read_as = _read(path, fmt)
        except MemoryError:
            return "memory", "MemoryError"
        except RecursionError:
            return "traceback", "RecursionError: " + traceback.format_exc(limit=-3)
        except GalileoError as error:
            pos = getattr(error, "pos", None)
            if pos is not None and pos.line >= 1 and f"{path}:{pos.line}" in str(error):
                return "positioned", str(error).splitlines()[0][len(str(path)):][:160]
            return "traceback", f"{type(error).__name__} without a position: {error}"[:400]
        except Exception:
            return "traceback", traceback.format_exc(limit=-4)[-1500:]
    runtime = [w for w in caught if issubclass(w.category, RuntimeWarning)]
    if runtime:
        w = runtime[0]
        return "traceback", f"RuntimeWarning at {w.filename}:{w.lineno}: {w.message}"
    bound = fmt_bounds.get(read_as, 10**15)
    if biggest > bound:
        return "traceback", f"read OK but a coordinate is {biggest} nm (bound {bound})"
    return "ok", f"{size} {'holes and slots' if read_as == 'drill' else 'ops'}"


def _child(seed: int, pools, directory: Path, memory_mb: int,
           formats: tuple[str, ...] = mutants.FORMATS) -> None:
    mutant = mutants.mutant(seed, pools, formats=formats)
    path = directory / f"mutant-{seed}{mutant.extension}"
    path.write_bytes(mutant.data)
    meta = {"fmt": mutant.fmt, "kind": mutant.kind, "source": mutant.source, "how": mutant.how}
    del mutant
    resettable = _reset_peak()
    base_kb = _status_kb("VmHWM") if resettable else resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    vm_bytes = _status_kb("VmSize") * 1024
    if vm_bytes:
        limit = vm_bytes + memory_mb * 1024 * 1024
        resource.setrlimit(resource.RLIMIT_AS, (limit, limit))
    outcome, detail = classify(str(path), fmt=meta["fmt"])
    peak_kb = _status_kb("VmHWM") if resettable else resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    grown_mb = (peak_kb - base_kb) / 1024
    if outcome != "memory" and grown_mb > memory_mb:
        outcome, detail = "memory", f"peak {grown_mb:.0f} MB above the start"
    result = {"outcome": outcome, "detail": detail, "grown_mb": round(grown_mb, 1), **meta}
    (directory / f"result-{seed}.json").write_text(json.dumps(result))
    path.unlink()


# --------------------------------------------------------------------------- parent

def _preload() -> None:
    """Import everything a read may need once, so children fork with it in place."""
    import galileo_cnc.readers  # noqa: F401
    import galileo_cnc.readers.dxf.emit  # noqa: F401
    import galileo_cnc.readers.dxf.load  # noqa: F401
    import galileo_cnc.readers.dxf.walk  # noqa: F401
    import ezdxf.lldxf.tagger  # noqa: F401


def run_campaign(seeds: list[int], jobs: int, timeout: float, memory_mb: int, pools,
                 progress: bool = True,
                 formats: tuple[str, ...] = mutants.FORMATS) -> dict[int, dict]:
    results: dict[int, dict] = {}
    with tempfile.TemporaryDirectory(prefix="galileo-fuzz-") as tmp:
        directory = Path(tmp)
        running: dict[int, tuple[int, float, float]] = {}  # pid -> (seed, start, deadline)
        pending = list(reversed(seeds))
        last_report = time.monotonic()
        while pending or running:
            while pending and len(running) < jobs:
                seed = pending.pop()
                pid = os.fork()
                if pid == 0:
                    code = 0
                    try:
                        signal.signal(signal.SIGINT, signal.SIG_DFL)
                        # CPU seconds: other work on the machine does not make a hang.
                        cpu = int(timeout) + 1
                        resource.setrlimit(resource.RLIMIT_CPU, (cpu, cpu + 5))
                        _child(seed, pools, directory, memory_mb, formats)
                    except BaseException:
                        traceback.print_exc()
                        code = 3
                    finally:
                        os._exit(code)
                now = time.monotonic()
                running[pid] = (seed, now, now + WALL_FACTOR * timeout)
            pid, status = os.waitpid(-1, os.WNOHANG)
            if pid == 0:
                now = time.monotonic()
                for pid, (seed, start, deadline) in list(running.items()):
                    if now > deadline:
                        os.kill(pid, signal.SIGKILL)
                        os.waitpid(pid, 0)
                        del running[pid]
                        results[seed] = {"outcome": "hang",
                                         "detail": f"killed after {WALL_FACTOR * timeout:g} s wall time"}
                time.sleep(0.002)
            else:
                seed, start, _ = running.pop(pid)
                result_file = directory / f"result-{seed}.json"
                if result_file.exists():
                    results[seed] = json.loads(result_file.read_text())
                    result_file.unlink()
                elif os.WIFSIGNALED(status) and os.WTERMSIG(status) in (signal.SIGXCPU, signal.SIGKILL):
                    results[seed] = {"outcome": "hang", "detail": f"over {timeout:g} s of CPU time"}
                elif os.WIFSIGNALED(status):
                    results[seed] = {"outcome": "traceback",
                                     "detail": f"child killed by signal {os.WTERMSIG(status)}"}
                else:
                    results[seed] = {"outcome": "traceback",
                                     "detail": f"child exited {os.WEXITSTATUS(status)} without a result"}
                results[seed]["seconds"] = round(time.monotonic() - start, 2)
                for leftover in directory.glob(f"mutant-{seed}.*"):
                    leftover.unlink()
            if progress and time.monotonic() - last_report > 30:
                last_report = time.monotonic()
                bad = sum(r["outcome"] in FAILURES for r in results.values())
                print(f"  ... {len(results)}/{len(seeds)} done, {bad} failures", file=sys.stderr)
    return results


def _table(rows: dict[str, Counter], title: str) -> str:
    head = f"{title:<14}" + "".join(f"{o:>12}" for o in OUTCOMES) + f"{'total':>8}"
    lines = [head, "-" * len(head)]
    total = Counter()
    for name in sorted(rows):
        counts = rows[name]
        total.update(counts)
        lines.append(f"{name:<14}" + "".join(f"{counts[o]:>12}" for o in OUTCOMES)
                     + f"{sum(counts.values()):>8}")
    lines.append("-" * len(head))
    lines.append(f"{'all':<14}" + "".join(f"{total[o]:>12}" for o in OUTCOMES)
                 + f"{sum(total.values()):>8}")
    return "\n".join(lines)


def report(results: dict[int, dict], pools,
           formats: tuple[str, ...] = mutants.FORMATS) -> int:
    by_kind: dict[str, Counter] = defaultdict(Counter)
    by_format: dict[str, Counter] = defaultdict(Counter)
    failures = []
    slowest = sorted(results.items(), key=lambda item: -item[1].get("seconds", 0))[:5]
    biggest = max((r.get("grown_mb", 0) for r in results.values()), default=0)
    for seed, result in sorted(results.items()):
        if "kind" not in result:  # a hang or a crash: the child could not say
            mutant = mutants.mutant(seed, pools, formats=formats)
            result.update(fmt=mutant.fmt, kind=mutant.kind, source=mutant.source, how=mutant.how)
        by_kind[result["kind"]][result["outcome"]] += 1
        by_format[result["fmt"]][result["outcome"]] += 1
        if result["outcome"] in FAILURES:
            failures.append((seed, result))
    print(_table(by_kind, "kind"))
    print()
    print(_table(by_format, "format"))
    print()
    print("slowest: " + ", ".join(f"seed {s} {r.get('seconds', 0):.1f} s" for s, r in slowest))
    print(f"largest memory growth: {biggest:.0f} MB")
    if failures:
        print(f"\n{len(failures)} failures (reproduce: python3 bench/bench_fuzz.py --show SEED):")
        for seed, result in failures:
            print(f"  seed {seed}: {result['outcome']}: {result['fmt']} {result['kind']} of "
                  f"{result['source']} ({result['how']})")
            for line in str(result["detail"]).strip().splitlines()[-3:]:
                print(f"      {line}")
    else:
        print("\nno failures")
    return 1 if failures else 0


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--mutants", type=int, default=10_000)
    parser.add_argument("--first", type=int, default=0, help="the first seed")
    parser.add_argument("--jobs", type=int, default=os.cpu_count() or 1)
    parser.add_argument("--timeout", type=float, default=20.0, help="seconds per mutant")
    parser.add_argument("--memory-mb", type=int, default=1024, help="memory per mutant")
    parser.add_argument("--formats", default=",".join(mutants.FORMATS),
                        help="mutants of these formats only (comma-separated: "
                        f"{','.join(mutants.FORMATS)})")
    parser.add_argument("--seeds", help="comma-separated seeds to run instead (e.g. failures)")
    parser.add_argument("--show", type=int, metavar="SEED", help="run one mutant here")
    parser.add_argument("--write", nargs=2, metavar=("SEED", "DIR"), help="write one mutant")
    parser.add_argument("--ci", action="store_true",
                        help="with --show/--write: the CI sample's mutant (small sizes, small pools)")
    args = parser.parse_args(argv)
    formats = tuple(f.strip() for f in args.formats.split(",") if f.strip())
    unknown = set(formats) - set(mutants.FORMATS)
    if unknown or not formats:
        parser.error(f"--formats: unknown {', '.join(sorted(unknown)) or 'empty'}")

    started = time.monotonic()
    pools = mutants.load_pools(max_gerber=30_000, max_dxf=40_000) if args.ci else mutants.load_pools()
    if args.write:
        mutant = mutants.mutant(int(args.write[0]), pools, ci=args.ci, formats=formats)
        path = Path(args.write[1]) / f"mutant-{mutant.seed}{mutant.extension}"
        path.write_bytes(mutant.data)
        print(f"{path}: {mutant.fmt} {mutant.kind} of {mutant.source} ({mutant.how}), "
              f"{len(mutant.data)} bytes")
        return 0
    if args.show is not None:
        from galileo_cnc.readers import read_drill, read_file

        mutant = mutants.mutant(args.show, pools, ci=args.ci, formats=formats)
        print(f"seed {mutant.seed}: {mutant.fmt} {mutant.kind} of {mutant.source} ({mutant.how}), "
              f"{len(mutant.data)} bytes")
        with tempfile.TemporaryDirectory() as tmp:
            path = Path(tmp) / f"mutant-{mutant.seed}{mutant.extension}"
            path.write_bytes(mutant.data)
            print(classify(str(path), fmt=mutant.fmt))
            try:
                (read_drill if mutant.fmt == "drill" else read_file)(path)
            except Exception:
                traceback.print_exc()
        return 0
    _preload()
    sources = {fmt: len(pools.of(fmt)) for fmt in formats}
    print((f"fuzz: {args.mutants} mutants, seeds {args.first}..{args.first + args.mutants - 1}, "
           if not args.seeds else f"fuzz: seeds {args.seeds}, ")
          + f"{args.jobs} jobs, {args.timeout:g} s and {args.memory_mb} MB each; sources "
          + ", ".join(f"{n} {fmt}" for fmt, n in sources.items()))
    seeds = [int(seed) for seed in args.seeds.split(",")] if args.seeds else \
        list(range(args.first, args.first + args.mutants))
    results = run_campaign(seeds, args.jobs,
                           args.timeout, args.memory_mb, pools, formats=formats)
    status = report(results, pools, formats)
    print(f"\n{len(results)} mutants in {time.monotonic() - started:.0f} s wall time")
    return status


if __name__ == "__main__":
    sys.exit(main())
