"""Path order: ours (plan/order/paths.py) against vpype's linemerge + linesort --two-opt.

Our chaining and ordering of pen paths and vpype's on the same paths, over the corpus,
in one run.

    python3 bench/bench_order.py                  # every copper layer and DXF drawing
    python3 bench/bench_order.py --quick          # a handful of small files
    python3 bench/bench_order.py --files 'gerber/kicad/*' --limit 5 --no-vpype

Files: every Gerber copper layer of /work/shared/corpus/gerber (the 'real' and
'derived' files that galileo_cnc.plan.ink.copper.looks_like_copper takes for copper,
as in bench_ink_union.py) and every DXF drawing of /work/shared/corpus/dxf (all but
the manifest's 'invalid' ones); a file the reader refuses is listed as skipped, with
the reason. `--files` matches names as printed ("gerber/...", "dxf/..."). A last row,
"synthetic", is 10,000 random short paths (2 to 4 points, 0.1 to 3 mm a segment, in a
200 mm square, seed 1), from (0, 0): it is not in the totals (`--synthetic N` changes
the count, 0 leaves it out; `--quick` uses 1,000, too few for check 2).

The paths, as plan/order/paths.py sees them: a Gerber file's rows are grouped one pen
per aperture as the planner does with `optimize=True` (`group_by_aperture`, then one
group per run of the same aperture, as in `apertures.optimized_order`; a single-aperture
file is one group in file order), a DXF drawing is one group; each group is cut into
pieces by `paths.cut_pieces`. Flashes are one-point paths for all three methods: they
are ordered, never joined (a flash ends with the pen up).

Three orders of the same pieces, each starting from the same point, the work origin
(`load_artwork(path).proposal_nm`, the program point the planner puts at the machine's
origin), each group starting where the same method's previous group ended:

  file   the file's order (one pen per aperture, the file's order within it): what the
         planner draws without `optimize`
  ours   `paths.optimize(rows, here, join_nm, goal=apertures.group_goal(next group))` per
         group, as `plan_program(..., optimize=True)` calls it through
         `apertures.optimize_groups`; its output re-cut with `cut_pieces` (a chain is one
         piece). Repeats it leaves out (plan/order/repeats.py) are not drawn, so its
         pieces can be fewer than the file's
  vpype  vpype (bench/order_peers.py) in its own venv: the same pieces as polylines
         (arcs flattened with `curves.arc_points` to 5 um, flashes as zero-length
         two-point lines), `LineCollection.merge(tolerance=6250, flip=True)` (= linemerge)
         on the paths, then vpype_cli's `linesort` function (two_opt, 250 passes) on the
         merged paths and the flashes, led by an anchor line at the start point (removed
         again: see order_peers.py)

vpype runs twice where the file draws something twice: on the file's pieces (check 1)
and on the pieces we draw, the repeats `plan/order/repeats.py` leaves out left out
(check 1b; the same pieces as check 1 where there are none). Leaving out a repeat of 5
mm or more can cost a stroke (its ends turn odd) and still save time, so on the file's
pieces ours can lift more than vpype while drawing less; 1b compares the two optimizers
on the same drawing.

Columns (one function, `measure`, computes travel and lifts for all three orders):
  paths     pieces in the file (paths and flashes), before any joining
  travel m  pen-up travel: the distance from the start point to the first piece, and
            from each piece's end to the next one's start, summed over the groups
  lifts     pen-downs: pieces after merging minus joins, where a join is a path that
            starts within join_nm = one motor step (6250 nm) of the end of the path
            before it in the same group (the pen stays down); each flash is one
  opt s     time to optimize: ours = `optimize` over every group; vpype = merge +
            linesort only (not its interpreter's start, not reading or writing .npz)
  plot s    Gerber copper layers: the reference machine's plot time
            (`machine.planner.estimate_seconds`) of `plan_program(program, config,
            proposal, optimize=False)` ("file") and `optimize=True` ("ours"), with the
            planner's default grouping (centre lines, one pen per aperture); a layer
            too big for the 200 mm travel is timed on the same machine with the travel
            widened to fit (marked +)
  !         after the ours numbers: worse than vpype on that file (travel by more than
            1 um, or more lifts)

vpype is installed only for this bench: bench/order_peers.py makes, once, a venv under
~/.cache/galileo-cnc-bench/vpype-venv (`python3 -m venv`, `pip install vpype`) and runs
the vpype side in that interpreter as a child process; paths go there and back as .npz
files in a temporary directory. If the venv cannot be made (no network), the bench
says so and runs our side only; `--no-vpype` skips it. Each file's vpype merge+sort is
cut off after `--vpype-timeout` s (reported; the file is then not compared).

Time limits: `--timeout` s (default 120) per file on our side (reading, cutting and
`optimize`), and within it 10 s + 5 ms a path for `optimize` on one group (several
times what the corpus's groups need); twice `--timeout` for a layer's two plans; `--vpype-timeout` for vpype's merge +
sort. A file past its limit is reported (which group, how many paths, where the head
was) and not compared; a copper layer whose `optimize` ran out of time is not planned
(plan_program(optimize=True) calls the same optimizer) and counts against check 3.

Process layout (2 CPUs here): the ordering child (reading, cutting, our optimizer) runs
first, alone; then the vpype child and the plot-time child (planning and timing the
copper layers) run side by side. Numbers are printed, never asserted; the closing
check lines say PASS or MISS against the targets of the issue.
"""

from __future__ import annotations

import argparse
import fnmatch
import json
import math
import subprocess
import sys
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))
sys.path.insert(0, str(REPO / "tests"))
sys.path.insert(0, str(Path(__file__).resolve().parent))

from corpus import CORPUS, manifest

import order_peers

DXF_CORPUS = CORPUS.parent / "dxf"
ARC_TOLERANCE_NM = 5000          # vpype's polylines: chord error of flattened arcs
SYNTHETIC = "synthetic"
SYNTHETIC_PATHS = 10_000
SYNTHETIC_SEED = 1
QUICK_BYTES = 30_000
QUICK_FILES = 4                  # per format
TRAVEL_SLACK_NM = 1000           # "worse than vpype": more than 1 um more travel
NM_PER_M = 1e9
#: our optimizer's time limit for one group: this plus this much per path (and within
#: the file's --timeout); several times what the corpus's groups need on a quiet machine
GROUP_LIMIT_S = 10.0
GROUP_LIMIT_PER_PATH_S = 0.005

# --------------------------------------------------------------------------- files


def copper_layers() -> list[tuple[str, int]]:
    """(relative path, bytes) of the corpus's Gerber copper layers (bench_ink_union.py)."""
    from galileo_cnc.plan.ink.copper import looks_like_copper

    found = []
    for row in manifest():
        if row["kind"] not in ("real", "derived"):
            continue
        head = (CORPUS / row["path"]).read_bytes()[:4000].decode("latin-1")
        if looks_like_copper(row["path"], head):
            found.append((row["path"], int(row["bytes"])))
    return found


def dxf_drawings() -> list[tuple[str, int]]:
    import csv

    if not (DXF_CORPUS / "MANIFEST.tsv").exists():
        return []
    with open(DXF_CORPUS / "MANIFEST.tsv", newline="") as handle:
        return [(row["path"], int(row["bytes"]))
                for row in csv.DictReader(handle, delimiter="\t") if row["kind"] != "invalid"]


def select_files(args) -> list[str]:
    """Names "gerber/<path>" and "dxf/<path>" of the files to run."""
    chosen = []
    for prefix, files in (("gerber", copper_layers()), ("dxf", dxf_drawings())):
        if args.quick:
            files = [f for f in files if f[1] <= QUICK_BYTES][:QUICK_FILES]
        chosen += [f"{prefix}/{path}" for path, _size in files]
    if args.files:
        chosen = [name for name in chosen if fnmatch.fnmatch(name, args.files)
                  or fnmatch.fnmatch(name.split("/", 1)[1], args.files)]
    return chosen[: args.limit]


def file_path(name: str) -> Path:
    prefix, path = name.split("/", 1)
    return (CORPUS if prefix == "gerber" else DXF_CORPUS) / path


# --------------------------------------------------------------------------- our side


def pen_groups(program) -> list[list[tuple[int, list[int]]]]:
    """Each pen's rows, in the planner's order: `optimized_order`'s split (one group per
    run of one aperture after `group_by_aperture`; a single pen is one group)."""
    from galileo_cnc.plan.order.apertures import drawing_apertures, group_by_aperture
    from galileo_cnc.program.ops import KIND, TOOL, OpKind

    by_aperture = program.format == "gerber" and len(drawing_apertures(program)) > 1
    rows = group_by_aperture(program) if by_aperture else list(enumerate(program.table.tolist()))
    groups: list[tuple[int | None, list]] = []
    for index, row in rows:
        if row[KIND] == OpKind.SELECT and by_aperture:
            if not groups or groups[-1][0] != row[TOOL]:
                groups.append((row[TOOL], []))
            continue
        if not groups:
            groups.append((None, []))
        groups[-1][1].append((index, row))
    return [group for _aperture, group in groups]


def synthetic_rows(count: int, seed: int) -> list[tuple[int, list[int]]]:
    """`count` random short open paths (MOVE, then 1..3 LINEs) in a 200 mm square."""
    import random

    from galileo_cnc.program.ops import COLUMNS, OpKind

    rng = random.Random(seed)
    rows = []
    for k in range(count):
        x, y = rng.randrange(200_000_000), rng.randrange(200_000_000)
        kind = int(OpKind.MOVE)
        for _ in range(rng.randint(2, 4)):
            row = [0] * len(COLUMNS)
            row[0], row[1], row[2] = kind, x, y
            rows.append((k, row))
            kind = int(OpKind.LINE)
            angle, length = rng.uniform(0, 2 * math.pi), rng.randint(100_000, 3_000_000)
            x, y = x + round(length * math.cos(angle)), y + round(length * math.sin(angle))
    return rows


def piece_ends(pieces):
    """(n, 5) float: start x, y, end x, y, flash (1.0) of each piece."""
    import numpy as np

    return np.array([(*p.start, *p.end, 0.0 if p.is_path else 1.0) for p in pieces],
                    dtype=float).reshape(-1, 5)


def polylines(pieces):
    """The pieces as vpype's polylines: (points, offsets, flash), arcs flattened."""
    import numpy as np

    from galileo_cnc.plan.curves import arc_points
    from galileo_cnc.program.ops import I, J, KIND, X, Y, OpKind

    arcs = (int(OpKind.ARC_CW), int(OpKind.ARC_CCW))
    chunks, offsets, flash = [], [0], []
    for piece in pieces:
        if not piece.is_path:
            chunks.append(np.array([piece.start, piece.start], dtype=float))
        else:
            points = [piece.start]
            for _index, row in piece.rows[1:]:
                if row[KIND] in arcs:
                    sx, sy = points[-1]
                    arc = arc_points(sx, sy, row[X], row[Y], row[I], row[J],
                                     row[KIND] == arcs[0], ARC_TOLERANCE_NM)
                    points.extend(map(tuple, arc[1:].tolist()))
                else:
                    points.append((row[X], row[Y]))
            chunks.append(np.array(points, dtype=float))
        offsets.append(offsets[-1] + len(chunks[-1]))
        flash.append(not piece.is_path)
    points = np.concatenate(chunks) if chunks else np.zeros((0, 2))
    return points, np.array(offsets, dtype=np.int64), np.array(flash, dtype=bool)


class Timeout(Exception):
    """A file ran past its time limit (raised by SIGALRM in a child)."""


def _alarm(_signum, _frame):
    raise Timeout()


def time_limit(seconds: float) -> None:
    """Arm (seconds > 0) or disarm (0) this child's alarm."""
    import signal

    signal.signal(signal.SIGALRM, _alarm)
    signal.setitimer(signal.ITIMER_REAL, seconds)


def child_order(names: list[str], out: Path, join_nm: int, synthetic: int,
                limit_s: float) -> None:
    """Per file: read and cut; write the ends of the file order to out/order/k.npz and
    the pieces as polylines to out/vpype-in/k.npz; then order (ours, timed, at most
    `limit_s` for the file) and add the ends of ours."""
    import numpy as np

    from galileo_cnc.plan.order.apertures import group_goal, pure_geometry
    from galileo_cnc.plan.order.paths import cut_pieces, optimize
    from galileo_cnc.plan.pipeline import load_artwork
    from galileo_cnc.plan.order.repeats import drop_repeats

    for k, name in enumerate(names):
        record: dict = {"k": k, "name": name}
        group, stage = 0, "read"
        try:
            time_limit(limit_s)
            started = time.perf_counter()
            if name == SYNTHETIC:
                groups, start, pure = [synthetic_rows(synthetic, SYNTHETIC_SEED)], (0, 0), True
            else:
                artwork = load_artwork(file_path(name))
                groups, start = pen_groups(artwork.program), artwork.proposal_nm
                pure = pure_geometry(artwork.program)
            record["read_s"] = time.perf_counter() - started
            stage = "cut"
            here = start
            order_npz = {}
            vpype_npz, drawn_npz = ({"start": np.array(start, dtype=float),
                                     "groups": len(groups)} for _ in range(2))
            sizes, repeats_left = [], False
            for g, rows in enumerate(groups):
                pieces = cut_pieces(rows, here)
                sizes.append(len(pieces))
                order_npz[f"file{g}"] = piece_ends(pieces)
                if pieces:
                    here = pieces[-1].end
                vpype_npz[f"p{g}"], vpype_npz[f"o{g}"], vpype_npz[f"f{g}"] = polylines(pieces)
                drawn = drop_repeats(pieces)
                repeats_left |= drawn is not pieces
                drawn_npz[f"p{g}"], drawn_npz[f"o{g}"], drawn_npz[f"f{g}"] = polylines(drawn)
            np.savez(out / "vpype-in" / f"{k}.npz", **vpype_npz)
            if repeats_left:
                np.savez(out / "vpype-in-drawn" / f"{k}.npz", **drawn_npz)
            record.update(start=list(start), groups=len(groups), paths=sum(sizes), pure=pure,
                          repeats_left=repeats_left)
            stage, seconds, here = "optimize", 0.0, start
            for group, rows in enumerate(groups):
                left = limit_s - (time.perf_counter() - started)
                record["limit_s"] = min(left, GROUP_LIMIT_S
                                        + GROUP_LIMIT_PER_PATH_S * sizes[group])
                time_limit(max(record["limit_s"], 0.001))
                t0 = time.perf_counter()
                goal = group_goal(groups[group + 1]) if group + 1 < len(groups) else None
                drawn, end = optimize(rows, here, join_nm, goal=goal)
                seconds += time.perf_counter() - t0
                order_npz[f"ours{group}"] = piece_ends(cut_pieces(drawn, here))
                here = end
            record["opt_s"] = seconds
            del record["limit_s"]
        except Timeout:
            record["timeout"] = limit_s
            record["stage"] = stage
            if stage == "optimize":
                record["timeout"] = record.pop("limit_s")
                ends = order_npz[f"file{group}"]
                record["hung"] = {"group": group, "paths": sizes[group],
                                  "here": list(here), "opt_s_before": seconds,
                                  "box": [int(ends[:, [0, 2]].min()), int(ends[:, [1, 3]].min()),
                                          int(ends[:, [0, 2]].max()), int(ends[:, [1, 3]].max())]
                                  if len(ends) else None}
        except Exception as problem:  # noqa: BLE001 (a failure is a result too)
            record["error"] = f"{type(problem).__name__}: {problem}"[:200]
        finally:
            time_limit(0)
        if "paths" in record:
            np.savez(out / "order" / f"{k}.npz", groups=len(groups), **order_npz)
        print(json.dumps(record), flush=True)


def widened(config, artwork):
    """`config`, or a copy whose travel fits the job (same dynamics), and whether widened."""
    from galileo_cnc.program.ops import NM_PER_MM

    if artwork.misfit(config) is None:
        return config, False
    x0, y0, x1, y1 = artwork.visited_box_nm
    room = 2 * artwork.margin_nm + 2 * NM_PER_MM
    return config.replace(
        x_travel_mm=max(config.x_travel_mm, math.ceil((x1 - x0 + room) / NM_PER_MM)),
        y_travel_mm=max(config.y_travel_mm, math.ceil((y1 - y0 + room) / NM_PER_MM))), True


def child_plot(names: list[str], todo: list[int], limit_s: float) -> None:
    """Per Gerber file k in `todo`: plot time (reference machine) of file order and of
    ours, at most `limit_s` for the file."""
    from galileo_cnc.config.machine import MachineConfig
    from galileo_cnc.machine.planner import estimate_seconds
    from galileo_cnc.plan.pipeline import load_artwork
    from galileo_cnc.plan.planner import plan_program

    base = MachineConfig()
    for k in todo:
        name = names[k]
        record: dict = {"k": k}
        try:
            time_limit(limit_s)
            artwork = load_artwork(file_path(name))
            config, record["widened"] = widened(base, artwork)
            for key, optimize in (("file_s", False), ("ours_s", True)):
                record["stage"] = f"plan_program(optimize={optimize})"
                job = plan_program(artwork.program, config, artwork.proposal_nm,
                                   optimize=optimize)
                record[key] = estimate_seconds(job.commands, config)
            del record["stage"]
        except Timeout:
            record["timeout"] = limit_s
        except Exception as problem:  # noqa: BLE001
            record["error"] = f"{type(problem).__name__}: {problem}"[:200]
        finally:
            time_limit(0)
        print(json.dumps(record), flush=True)


# --------------------------------------------------------------------------- measure


def measure(groups, start, join_nm: float) -> tuple[float, int, int]:
    """(pen-up travel nm, lifts, pieces) of drawing `groups` (each an (n, 5) array of
    start x, y, end x, y, flash) one after another from `start`: the same for all three
    orders. A piece is a join (no lift) when it and the one before it in its group are
    paths and it starts within `join_nm` of that one's end."""
    import numpy as np

    travel, lifts, pieces = 0.0, 0, 0
    here = (float(start[0]), float(start[1]))
    for ends in groups:
        if not len(ends):
            continue
        before = np.vstack([[here], ends[:-1, 2:4]])
        gaps = np.hypot(ends[:, 0] - before[:, 0], ends[:, 1] - before[:, 1])
        flash = ends[:, 4] > 0
        joins = (gaps <= join_nm) & ~flash & ~np.r_[True, flash[:-1]]
        joins[0] = False                    # the group's first piece: the pen is up
        travel += float(gaps.sum())
        lifts += int(len(ends) - joins.sum())
        pieces += len(ends)
        here = (float(ends[-1, 2]), float(ends[-1, 3]))
    return travel, lifts, pieces


def vpype_ends(path: Path):
    """The (n, 5) end arrays of the vpype child's output groups."""
    import numpy as np

    data = np.load(path)
    groups = []
    for g in range(int(data["groups"])):
        points, offsets, flash = data[f"p{g}"], data[f"o{g}"], data[f"f{g}"]
        n = len(flash)
        ends = np.zeros((n, 5))
        if n:
            ends[:, 0:2] = points[offsets[:-1]]
            ends[:, 2:4] = points[offsets[1:] - 1]
            ends[:, 4] = flash
        groups.append(ends)
    return groups


# --------------------------------------------------------------------------- parent


def run_child(command: list[str], expected: int, what: str, background: bool = False):
    """Run a child that prints one JSON line per file; with `background` return the
    Popen, else its records."""
    if background:
        return subprocess.Popen(command, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                                text=True)
    started = time.perf_counter()
    done = subprocess.run(command, capture_output=True, text=True, check=False)
    return collect(done.returncode, done.stdout, done.stderr, expected, what, started)


def collect(code: int, stdout: str, stderr: str, expected: int, what: str,
            started: float) -> list[dict]:
    records = [json.loads(line) for line in stdout.splitlines() if line.startswith("{")]
    if code or len(records) != expected:
        sys.stderr.write(stderr[-3000:])
        print(f"  {what}: child stopped after {len(records)} of {expected} files "
              f"(exit {code})", file=sys.stderr)
    print(f"  {what}: {time.perf_counter() - started:.1f} s wall", file=sys.stderr)
    return records


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true",
                    help=f"{QUICK_FILES} copper layers and {QUICK_FILES} DXF drawings up to "
                         f"{QUICK_BYTES // 1000} kB, and a 1,000-path synthetic case")
    ap.add_argument("--limit", type=int, default=None, help="first N files only")
    ap.add_argument("--files", help="only names matching this glob (e.g. 'gerber/kicad/*')")
    ap.add_argument("--no-vpype", action="store_true", help="our side only")
    ap.add_argument("--vpype-timeout", type=float, default=120.0,
                    help="seconds for one file's vpype merge+sort (default 120)")
    ap.add_argument("--timeout", type=float, default=120.0,
                    help="seconds for one file on our side: reading, cutting and our "
                         "optimizer; twice that for its plot times (default 120)")
    ap.add_argument("--synthetic", type=int, default=None,
                    help=f"paths of the synthetic case (default {SYNTHETIC_PATHS:,}; 0: none)")
    ap.add_argument("--child", help=argparse.SUPPRESS)
    ap.add_argument("--listing", help=argparse.SUPPRESS)
    ap.add_argument("--out", help=argparse.SUPPRESS)
    args = ap.parse_args()
    import numpy as np

    from galileo_cnc.config.machine import MachineConfig

    join_nm = MachineConfig().nm_per_step
    synthetic = args.synthetic if args.synthetic is not None else (
        1000 if args.quick else SYNTHETIC_PATHS)
    if args.child:
        names = json.loads(Path(args.listing).read_text())
        if args.child == "order":
            child_order(names, Path(args.out), join_nm, synthetic, args.timeout)
        else:
            child_plot(names, json.loads((Path(args.out) / "plot.json").read_text()),
                       2 * args.timeout)
        return

    wall = time.perf_counter()
    names = select_files(args)
    gerbers = sum(name.startswith("gerber/") for name in names)
    print(f"{gerbers} copper layers, {len(names) - gerbers} DXF drawings"
          + (f", synthetic case of {synthetic:,} paths" if synthetic else "")
          + f"; join tolerance {join_nm} nm", file=sys.stderr)
    if synthetic:
        names.append(SYNTHETIC)
    peer = None if args.no_vpype else order_peers.vpype_python(
        lambda text: print(text, file=sys.stderr))
    if peer is None and not args.no_vpype:
        print("vpype: no venv, so our side only", file=sys.stderr)

    with tempfile.TemporaryDirectory() as scratch:
        out = Path(scratch)
        for folder in ("order", "vpype-in", "vpype-out", "vpype-in-drawn", "vpype-out-drawn"):
            (out / folder).mkdir()
        listing = out / "files.json"
        listing.write_text(json.dumps(names))
        me = [sys.executable, __file__, "--listing", str(listing), "--out", str(out)]
        me += ["--synthetic", str(synthetic), "--timeout", str(args.timeout)]
        order = run_child(me + ["--child", "order"], len(names), "order (ours)")
        # plot times beside vpype; not for a layer our optimizer could not finish
        # (plan_program(optimize=True) would not finish either)
        todo = [r["k"] for r in order if names[r["k"]].startswith("gerber/")
                and "opt_s" in r]
        (out / "plot.json").write_text(json.dumps(todo))
        plot_started = time.perf_counter()
        plotter = run_child(me + ["--child", "plot"], 0, "plot", background=True)
        vpype: dict[int, dict] = {}
        vpype_drawn: dict[int, dict] = {}
        if peer is not None:
            for suffix, ready, found in (
                    ("", [r["k"] for r in order if "paths" in r], vpype),
                    ("-drawn", [r["k"] for r in order if r.get("repeats_left")], vpype_drawn)):
                listed = out / f"vpype{suffix}.json"
                listed.write_text(json.dumps(ready))
                command = [str(peer[0]), str(Path(order_peers.__file__).resolve()), "--child",
                           str(out / f"vpype-in{suffix}"), str(out / f"vpype-out{suffix}"),
                           str(listed), str(args.vpype_timeout), str(join_nm)]
                found.update((r["k"], r) for r in run_child(
                    command, len(ready), f"vpype {peer[1]}{' (paths drawn)' if suffix else ''}"))
        stdout, stderr = plotter.communicate()
        plots = {r["k"]: r for r in collect(plotter.returncode, stdout, stderr, len(todo),
                                            "plot", plot_started)}
        rows = []
        for record in order:
            k = record["k"]
            row = {"name": names[k], "order": record, "plot": plots.get(k),
                   "vpype": vpype.get(k)}
            if "paths" in record:
                data = np.load(out / "order" / f"{k}.npz")
                groups = int(data["groups"])
                for method in ("file", "ours") if "opt_s" in record else ("file",):
                    row[method] = measure([data[f"{method}{g}"] for g in range(groups)],
                                          record["start"], join_nm)
                if k in vpype and "seconds" in vpype[k]:
                    row["vp"] = measure(vpype_ends(out / "vpype-out" / f"{k}.npz"),
                                        record["start"], join_nm)
                    row["vp_drawn"] = row["vp"]
                    if record.get("repeats_left"):
                        done = vpype_drawn.get(k, {})
                        row["vp_drawn"] = measure(vpype_ends(
                            out / "vpype-out-drawn" / f"{k}.npz"), record["start"],
                            join_nm) if "seconds" in done else None
            rows.append(row)
    report(rows, peer, join_nm, synthetic, args)
    print(f"\nwall time {time.perf_counter() - wall:.0f} s")


# --------------------------------------------------------------------------- report


def check_against(compared, key, label, what, peer, timed_out, hung) -> str:
    """List the files where ours is worse than vpype's order `key`; the check line."""
    if peer is None:
        return f"check {label} (travel and lifts vs vpype): SKIP (no vpype)"
    both = [r for r in compared if r.get(key) is not None]
    losers = [r for r in both if worse(r, key)]
    travel_losers = sorted((r for r in losers if r["ours"][0] > r[key][0] + TRAVEL_SLACK_NM),
                           key=lambda r: -r["ours"][0] / max(r[key][0], 1))
    lift_losers = sorted((r for r in losers if r["ours"][1] > r[key][1]),
                         key=lambda r: r[key][1] - r["ours"][1])
    for title, subset in (("more travel", travel_losers), ("more lifts", lift_losers)):
        if not subset:
            continue
        print(f"\nfiles where ours has {title} than {what} ({len(subset)}):")
        for r in subset:
            print(f"  {r['name']}: travel ours {r['ours'][0] / NM_PER_M:.4f} m vs vpype "
                  f"{r[key][0] / NM_PER_M:.4f} m ({r['ours'][0] / max(r[key][0], 1):.3f}x), "
                  f"lifts {r['ours'][1]} vs {r[key][1]}, paths after merging "
                  f"{r['ours'][2]} vs {r[key][2]} (of {r['order']['paths']} in "
                  f"{r['order']['groups']} groups)"
                  + (", vpype's anchor moved" if r["vpype"]["anchor_moved"] else ""))
    travel = (sum(r["ours"][0] for r in both), sum(r[key][0] for r in both))
    lifts = (sum(r["ours"][1] for r in both), sum(r[key][1] for r in both))
    missing = len(compared) - len(both)
    ok = both and not losers and travel[0] < travel[1] and lifts[0] <= lifts[1] \
        and not timed_out and not hung and not missing
    return (f"check {label} (travel and lifts no worse than {what}, on every file; travel "
            f"lower and lifts no more in total): {'PASS' if ok else 'MISS'}: worse on "
            f"{len(losers)} of {len(both)} files ({len(travel_losers)} more travel, "
            f"{len(lift_losers)} more lifts); travel {travel[0] / NM_PER_M:.2f} vs "
            f"{travel[1] / NM_PER_M:.2f} m, lifts {lifts[0]:,} vs {lifts[1]:,}"
            + (f"; {missing} files not compared (vpype failed on the paths drawn)"
               if missing else "")
            + (f"; {len(timed_out)} files not compared (vpype timed out)" if timed_out else "")
            + (f"; ours timed out on {len(hung)} files" if hung else ""))


def worse(row, peer_key: str = "vp") -> bool:
    """Ours worse than vpype's order (`peer_key` "vp": of the file's paths; "vp_drawn":
    of the paths left once repeats are left out) on this file."""
    vp = row.get(peer_key)
    return vp is not None and "ours" in row and (
        row["ours"][0] > vp[0] + TRAVEL_SLACK_NM or row["ours"][1] > vp[1])


def report(rows, peer, join_nm, synthetic, args) -> None:
    head = (f"{'file':48} {'paths':>6} | {'travel m: file':>14} {'ours':>7} {'vpype':>7} | "
            f"{'lifts: file':>11} {'ours':>6} {'vpype':>6} | {'opt s: ours':>11} {'vpype':>7} | "
            f"{'plot s: file':>12} {'ours':>7} {'x':>5}")
    print(head)
    print("-" * len(head))
    skipped = []

    def metric(row, method, field, width, scale=1.0, digits=0):
        if method not in row:
            return f"{'-':>{width}}"
        return f"{row[method][field] / scale:{width}.{digits}f}"

    for row in rows:
        o, vp, plot = row["order"], row.get("vpype") or {}, row.get("plot") or {}
        if "paths" not in o:
            skipped.append((row["name"], o.get("error") or
                            f"over {o['timeout']:g} s while {o['stage']}"))
            continue
        flag = "!" if worse(row) else " "
        line = (f"{row['name'][-48:]:48} {o['paths']:6d} | "
                f"{metric(row, 'file', 0, 14, NM_PER_M, 3)} {metric(row, 'ours', 0, 7, NM_PER_M, 3)} "
                f"{metric(row, 'vp', 0, 7, NM_PER_M, 3)} | {metric(row, 'file', 1, 11)} "
                f"{metric(row, 'ours', 1, 6)}{flag}{metric(row, 'vp', 1, 6)} | ")
        line += f"{o['opt_s']:11.2f} " if "opt_s" in o else f"{'>' + format(o['timeout'], '.0f'):>11} "
        if "seconds" in vp:
            line += f"{vp['seconds']:7.2f} | "
        elif "timeout" in vp:
            line += f"{'>' + format(vp['timeout'], 'g'):>7} | "
        else:
            line += f"{'-':>7} | "
        if "file_s" in plot and "ours_s" in plot:
            mark = "+" if plot["widened"] else " "
            line += f"{plot['file_s']:11.0f}{mark} {plot['ours_s']:7.0f} " \
                    f"{plot['ours_s'] / plot['file_s']:5.2f}"
        elif "timeout" in plot:
            line += f"{'>' + format(plot['timeout'], 'g') + ' s':>12}"
        elif "error" in plot:
            line += f"{'error':>12}"
        if not o["pure"]:
            line += "  (not pure geometry: the planner would not reorder it)"
        print(line)

    files = [r for r in rows if "ours" in r and r["name"] != SYNTHETIC]
    hung = [r for r in rows if "paths" in r["order"] and "ours" not in r]
    compared = [r for r in files if "vp" in r]
    timed_out = [r for r in files if r.get("vpype") and "timeout" in r["vpype"]]
    vp_errors = [r for r in files if r.get("vpype") and "error" in r["vpype"]]
    plotted = [r for r in files + hung if r.get("plot") and "ours_s" in r["plot"]]

    def total(subset, method, field):
        return sum(r[method][field] for r in subset)

    print()
    for label, subset in (("all", files),
                          ("gerber", [r for r in files if r["name"].startswith("gerber/")]),
                          ("dxf", [r for r in files if r["name"].startswith("dxf/")])):
        if not subset:
            continue
        line = (f"totals {label:6} {len(subset):3d} files "
                f"{sum(r['order']['paths'] for r in subset):8,} paths: travel m file "
                f"{total(subset, 'file', 0) / NM_PER_M:9.2f} ours "
                f"{total(subset, 'ours', 0) / NM_PER_M:9.2f}; lifts file "
                f"{total(subset, 'file', 1):7,} ours {total(subset, 'ours', 1):7,}; opt s ours "
                f"{sum(r['order']['opt_s'] for r in subset):6.1f}")
        both = [r for r in subset if "vp" in r]
        if peer is not None:
            ratios = [r["ours"][0] / r["vp"][0] for r in both if r["vp"][0] > 0]
            geomean = math.exp(sum(map(math.log, ratios)) / len(ratios)) if ratios else float("nan")
            line += (f"\n  {'':6} {len(both):3d} with vpype: travel m file "
                     f"{total(both, 'file', 0) / NM_PER_M:9.2f} ours "
                     f"{total(both, 'ours', 0) / NM_PER_M:9.2f} vpype "
                     f"{total(both, 'vp', 0) / NM_PER_M:9.2f} (ours/vpype per file: geometric "
                     f"mean {geomean:.3f}, worst {max(ratios, default=float('nan')):.3f}); "
                     f"lifts file {total(both, 'file', 1):,} ours {total(both, 'ours', 1):,} "
                     f"vpype {total(both, 'vp', 1):,}; opt s ours "
                     f"{sum(r['order']['opt_s'] for r in both):.1f} vpype "
                     f"{sum(r['vpype']['seconds'] for r in both):.1f} (merge "
                     f"{sum(r['vpype']['merge_s'] for r in both):.1f} + sort "
                     f"{sum(r['vpype']['sort_s'] for r in both):.1f})")
        print(line)
    if compared:
        moved = [r for r in compared if r["vpype"]["anchor_moved"]]
        print(f"vpype's 2-opt moved the start anchor in {len(moved)} of {len(compared)} files; "
              f"its first legs there (start to vpype's first path, which vpype does not "
              f"shorten) add up to {sum(r['vpype']['first_leg'] for r in moved) / NM_PER_M:.3f} m")
    if plotted:
        file_s, ours_s = (sum(r["plot"][key] for r in plotted) for key in ("file_s", "ours_s"))
        print(f"plot time of {len(plotted)} copper layers: file order {file_s / 3600:.1f} h, "
              f"ours {ours_s / 3600:.1f} h ({ours_s / file_s:.2f}x); "
              f"{sum(r['plot']['widened'] for r in plotted)} timed with a widened travel (+)")
    for name, problem in skipped:
        print(f"skipped {name}: {problem}")
    for r in hung:
        h, vp = r["order"].get("hung", {}), r.get("vpype") or {}
        print(f"OURS TIMED OUT on {r['name']} after {r['order']['timeout']:.0f} s in `optimize`, "
              f"group {h.get('group')} of {r['order']['groups']} ({h.get('paths')} paths), "
              f"starting at {tuple(h.get('here', ()))} nm, its paths within "
              f"{tuple(h.get('box') or ())} nm; file order {r['file'][0] / NM_PER_M:.3f}"
              f" m, {r['file'][1]} lifts"
              + (f"; vpype {r['vp'][0] / NM_PER_M:.3f} m, {r['vp'][1]} lifts in "
                 f"{vp['seconds']:.2f} s" if "vp" in r else ""))
    for r in rows:
        if r.get("plot") and "timeout" in r["plot"]:
            print(f"plot time timed out on {r['name']} after {r['plot']['timeout']:g} s in "
                  f"{r['plot'].get('stage', '?')}")
    for r in timed_out:
        print(f"vpype timed out on {r['name']} ({r['order']['paths']} paths) after "
              f"{r['vpype']['timeout']:g} s: not compared")
    for r in vp_errors:
        print(f"vpype failed on {r['name']}: {r['vpype']['error']}")
    for r in files + hung:
        if r.get("plot") and "error" in r["plot"]:
            print(f"plot time failed on {r['name']}: {r['plot']['error']}")

    verdicts = []
    for key, label, what in (
            ("vp", "1", "vpype given the file's paths"),
            ("vp_drawn", "1b", "vpype given the paths we draw: the file's, the repeats "
                               "plan/order/repeats.py leaves out left out")):
        verdicts.append(check_against(compared, key, label, what, peer, timed_out, hung))
    print()
    for line in verdicts:
        print(line)
    synth = next((r for r in rows if r["name"] == SYNTHETIC and "opt_s" in r["order"]), None)
    if synth is None:
        print("check 2 (10,000 paths in under 2 s): SKIP (no synthetic case)")
    else:
        vp = synth.get("vpype") or {}
        vp_text = (f"; vpype {vp['seconds']:.2f} s" if "seconds" in vp else
                   f"; vpype over {vp['timeout']:g} s" if "timeout" in vp else "")
        n, seconds = synth["order"]["paths"], synth["order"]["opt_s"]
        verdict = ("PASS" if seconds < 2.0 else "MISS") if n >= SYNTHETIC_PATHS else \
            f"SKIP (only {n:,} paths)"
        print(f"check 2 (optimizing 10,000 paths in under 2 s): {verdict}: ours "
              f"{seconds:.2f} s for {n:,} paths{vp_text}")
    stuck = [r for r in rows if r.get("plot") and "timeout" in r["plot"]] + [
        r for r in hung if r["name"].startswith("gerber/")]
    if plotted:
        print(f"check 3 (copper plot time, ours at most 0.6x of file order): "
              f"{'PASS' if ours_s <= 0.6 * file_s and not stuck else 'MISS'}: "
              f"{ours_s / 3600:.2f} h vs {file_s / 3600:.2f} h = {ours_s / file_s:.3f}x over "
              f"{len(plotted)} layers"
              + (f"; {len(stuck)} layers could not be planned with optimize=True in time "
                 f"(see above)" if stuck else ""))
    else:
        print("check 3 (copper plot time): SKIP (no copper layer timed)")


if __name__ == "__main__":
    main()
