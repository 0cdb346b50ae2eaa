"""Gerber reader throughput and peak memory: ours vs gerbonara vs pygerber; and the
Excellon column: our drill reader vs gerbonara's on the corpus's drill files.

    python bench/bench_readers.py            # whole corpus (real/synthetic/derived)
    python bench/bench_readers.py --quick    # files up to 100 kB only
    python bench/bench_readers.py --limit 40 --readers ours,gerbonara

Each reader runs in its own child process, over the same file list, one file after
another; ours and gerbonara run in alternating rounds and keep each file's best
time. Why a child per reader rather than tracemalloc in one process:
tracemalloc hooks every allocation and slows pure-Python parsers (both peers) far
more than ours, which would skew the very throughput we compare; and a fresh
process's peak RSS (`resource.getrusage(...).ru_maxrss`) counts everything the reader
holds, numpy buffers and pydantic models included, without one reader's leftovers
inflating the next. The child reports its RSS after imports (baseline) and its peak;
"peak - base" is what reading the largest file cost.

Timing covers path -> parsed object (file read included; the OS cache is warm after
the first reader). A file a peer cannot read counts as a failure and is left out of
that peer's throughput AND out of ours in that peer's ratio, so every ratio compares
the same bytes. The peers run exactly as tests/peers.py runs them: gerbonara's
GerberFile.open (warnings silenced), pygerber's Tokenizer + Parser2 with errors
raised (what its v2 API does with OnParserErrorEnum.Raise, without the bounding box
that API computes on top).

The Excellon column runs in the same way, in the same run, over the manifest's
"drill" files (drill/ folder, route files included): `read_drill` against
gerbonara's ExcellonFile.open; --readers ours,gerbonara without "excellon" leaves it
out, and --readers excellon runs it alone.
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import subprocess
import sys
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))
sys.path.insert(0, str(REPO / "tests"))

import peers  # noqa: E402  (tests/peers.py: corpus location, how each peer is called)

READERS = ("ours", "gerbonara", "pygerber", "excellon")
DRILL_READERS = ("ours-drill", "gerbonara-drill")   # what "excellon" runs
QUICK_MAX_BYTES = 100_000
TARGETS = {"gerbonara": 3.0, "pygerber": 100.0}


# --------------------------------------------------------------------------- child


def _reader(name: str):
    """A function path -> parsed object, with imports done before timing."""
    if name == "ours":
        from galileo_cnc.readers.gerber import read_gerber

        return read_gerber
    if name == "gerbonara":
        return peers.gerbonara_read
    if name == "ours-drill":
        from galileo_cnc.readers import read_drill

        return read_drill
    if name == "gerbonara-drill":
        import warnings

        from gerbonara.excellon import ExcellonFile

        def gerbonara_drill(path):
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                return ExcellonFile.open(path)
        return gerbonara_drill
    if name == "pygerber":
        import logging

        logging.disable(logging.WARNING)  # pygerber logs style advice per file
        peers.pygerber_parse("G04 warm-up*\nM02*\n", is_text=True)  # builds the grammar
        return peers.pygerber_parse
    raise SystemExit(f"unknown reader {name}")


def _maxrss_bytes() -> int:
    rss = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    return rss if sys.platform == "darwin" else rss * 1024


def child(name: str, files: list[str]) -> None:
    read = _reader(name)
    print(json.dumps({"base_rss": _maxrss_bytes()}), flush=True)
    for path in files:
        t0 = time.perf_counter()
        try:
            read(path)      # the result is dropped at once: peak memory is one file's
            err = None
        except Exception as e:  # a peer failing is data, not a crash
            err = f"{type(e).__name__}: {str(e).splitlines()[0][:160] if str(e) else ''}"
        dt = time.perf_counter() - t0
        print(json.dumps({"path": path, "s": dt, "err": err}), flush=True)
    print(json.dumps({"peak_rss": _maxrss_bytes()}), flush=True)


# --------------------------------------------------------------------------- parent


def run_reader(name: str, files: list[str], sizes: dict[str, tuple[int, int]]) -> dict:
    proc = subprocess.Popen([sys.executable, __file__, "--child", name],
                            stdin=subprocess.PIPE, stdout=subprocess.PIPE,
                            text=True, cwd=REPO)
    proc.stdin.write("\n".join(files))
    proc.stdin.close()
    res = {"times": {}, "errors": {}, "base_rss": 0, "peak_rss": 0}
    done = 0
    for line in proc.stdout:
        rec = json.loads(line)
        if "path" in rec:
            done += 1
            if rec["err"]:
                res["errors"][rec["path"]] = rec["err"]
            else:
                res["times"][rec["path"]] = rec["s"]
            if sys.stderr.isatty():
                print(f"\r  {name:10s} {done}/{len(files)}", end="", file=sys.stderr, flush=True)
        else:
            res.update(rec)
    if sys.stderr.isatty():
        print(file=sys.stderr)
    if proc.wait() != 0:
        res["crashed"] = proc.returncode
    return res


def merge_best(results: dict, name: str, res: dict) -> None:
    """Fold one round into `results`: best time per file, highest RSS."""
    if name not in results:
        results[name] = res
        return
    best = results[name]
    for path, seconds in res["times"].items():
        best["times"][path] = min(seconds, best["times"].get(path, seconds))
    best["peak_rss"] = max(best["peak_rss"], res["peak_rss"])


def throughput(res: dict, paths, sizes) -> tuple[float, float, float, int]:
    """(MB/s, lines/s, seconds, bytes) over `paths`."""
    secs = sum(res["times"][p] for p in paths)
    nbytes = sum(sizes[p][0] for p in paths)
    nlines = sum(sizes[p][1] for p in paths)
    if secs == 0:
        return 0.0, 0.0, 0.0, nbytes
    return nbytes / secs / 1e6, nlines / secs, secs, nbytes


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--limit", type=int, help="only the first N files (largest first)")
    ap.add_argument("--quick", action="store_true",
                    help=f"only files up to {QUICK_MAX_BYTES // 1000} kB")
    ap.add_argument("--readers", default=",".join(READERS),
                    help="comma-separated subset of " + ",".join(READERS))
    ap.add_argument("--show-failures", action="store_true", help="list every failed file")
    ap.add_argument("--rounds", type=int, default=3,
                    help="rounds of ours and gerbonara, best time per file (default 3)")
    ap.add_argument("--child", help=argparse.SUPPRESS)
    args = ap.parse_args(argv)

    if args.child:
        child(args.child, [p for p in sys.stdin.read().splitlines() if p])
        return 0

    root = peers.corpus_dir()
    rows = peers.corpus_files()
    if not rows:
        print(f"no corpus at {root}", file=sys.stderr)
        return 2
    if args.quick:
        rows = [r for r in rows if r.bytes <= QUICK_MAX_BYTES]
    rows.sort(key=lambda r: -r.bytes)
    if args.limit:
        rows = rows[: args.limit]
    files = [str(root / r.path) for r in rows]
    sizes = file_sizes(files)
    readers = [r for r in args.readers.split(",") if r]
    drill = "excellon" in readers
    readers = [r for r in readers if r != "excellon"]
    if not readers:
        return excellon_column(root, args.rounds, args.show_failures)

    total_bytes = sum(s[0] for s in sizes.values())
    total_lines = sum(s[1] for s in sizes.values())
    print(f"corpus {root}: {len(files)} files, {total_bytes / 1e6:.1f} MB, "
          f"{total_lines:,} lines; python {sys.version.split()[0]}, "
          f"{os.cpu_count()} cpus, readers run one after another in child processes, "
          f"{args.rounds} rounds")

    # Rounds alternate the readers, and each file keeps its best time over the rounds,
    # so a burst of load on a shared machine does not land on one reader only.
    # pygerber is some 200 times slower than the others: one round of it.
    results: dict[str, dict] = {}
    for round_number in range(args.rounds):
        for name in readers:
            if name == "pygerber" and round_number:
                continue
            merge_best(results, name, run_reader(name, files, sizes))

    print()
    print(f"{'reader':10s} {'files ok':>9s} {'failed':>7s} {'MB':>7s} {'seconds':>9s} "
          f"{'MB/s':>8s} {'lines/s':>11s} {'RSS base':>9s} {'RSS peak':>9s}")
    for name in readers:
        res = results[name]
        ok = list(res["times"])
        mbs, lps, secs, nbytes = throughput(res, ok, sizes)
        print(f"{name:10s} {len(ok):9d} {len(res['errors']):7d} {nbytes / 1e6:7.1f} "
              f"{secs:9.2f} {mbs:8.3f} {lps:11,.0f} {res['base_rss'] / 2**20:7.0f}MB "
              f"{res['peak_rss'] / 2**20:7.0f}MB" + ("  CRASHED" if "crashed" in res else ""))

    if "ours" in results:
        print()
        print("ratios on the same bytes (files both readers read):")
        ours = results["ours"]
        for name in readers:
            if name == "ours":
                continue
            common = [f for f in files if f in ours["times"] and f in results[name]["times"]]
            o_mbs, _, o_s, nbytes = throughput(ours, common, sizes)
            p_mbs, _, p_s, _ = throughput(results[name], common, sizes)
            ratio = (p_s / o_s) if o_s else float("nan")
            target = TARGETS.get(name)
            verdict = "" if target is None else (
                f"target >= {target:g}x: {'met' if ratio >= target else 'NOT met'}")
            print(f"  ours/{name:10s} {ratio:8.1f}x  on {len(common)} files, "
                  f"{nbytes / 1e6:.1f} MB (ours {o_mbs:.3f} MB/s, {name} {p_mbs:.3f} MB/s)"
                  f"  {verdict}")

    print_failures(results, readers, root, args.show_failures)
    if drill:
        print()
        excellon_column(root, args.rounds, args.show_failures)
    return 0


def print_failures(results: dict, readers, root: Path, show: bool) -> None:
    for name in readers:
        errs = results[name]["errors"]
        if not errs:
            continue
        kinds: dict[str, int] = {}
        for e in errs.values():
            key = e.split(":")[0]
            kinds[key] = kinds.get(key, 0) + 1
        summary = ", ".join(f"{k} x{n}" for k, n in sorted(kinds.items(), key=lambda kv: -kv[1]))
        print(f"\n{name}: {len(errs)} files failed ({summary})")
        if show:
            for f, e in errs.items():
                print(f"  {Path(f).relative_to(root)}: {e}")


def file_sizes(files: list[str]) -> dict[str, tuple[int, int]]:
    """Bytes and lines (a last line without a newline counts) of each file."""
    sizes = {}
    for f in files:
        data = Path(f).read_bytes()
        sizes[f] = (len(data), data.count(b"\n") + (not data.endswith(b"\n")))
    return sizes


def excellon_column(root: Path, rounds: int, show_failures: bool) -> int:
    """Our Excellon reader and gerbonara's over the corpus's drill files, in alternating
    rounds (best time per file), with the ratio on the files both read."""
    rows = peers.corpus_files(kinds=("drill",))
    files = [str(root / r.path) for r in sorted(rows, key=lambda r: -r.bytes)]
    if not files:
        print(f"excellon: no drill files in {root}")
        return 0
    sizes = file_sizes(files)
    results: dict[str, dict] = {}
    for _ in range(rounds):
        for name in DRILL_READERS:
            merge_best(results, name, run_reader(name, files, sizes))
    print(f"Excellon: {len(files)} drill files, {sum(s[0] for s in sizes.values()) / 1e6:.2f} MB, "
          f"{sum(s[1] for s in sizes.values()):,} lines")
    print(f"{'reader':16s} {'files ok':>9s} {'failed':>7s} {'MB':>7s} {'seconds':>9s} "
          f"{'MB/s':>8s} {'lines/s':>11s}")
    for name in DRILL_READERS:
        res = results[name]
        ok = list(res["times"])
        mbs, lps, secs, nbytes = throughput(res, ok, sizes)
        print(f"{name:16s} {len(ok):9d} {len(res['errors']):7d} {nbytes / 1e6:7.2f} "
              f"{secs:9.3f} {mbs:8.3f} {lps:11,.0f}" + ("  CRASHED" if "crashed" in res else ""))
    ours, theirs = results["ours-drill"], results["gerbonara-drill"]
    common = [f for f in files if f in ours["times"] and f in theirs["times"]]
    o_mbs, _, o_s, nbytes = throughput(ours, common, sizes)
    p_mbs, _, p_s, _ = throughput(theirs, common, sizes)
    print(f"  ours/gerbonara {p_s / o_s if o_s else float('nan'):8.1f}x  on {len(common)} files, "
          f"{nbytes / 1e6:.2f} MB (ours {o_mbs:.3f} MB/s, gerbonara {p_mbs:.3f} MB/s)")
    print_failures(results, DRILL_READERS, root, show_failures)
    return 0


if __name__ == "__main__":
    sys.exit(main())
