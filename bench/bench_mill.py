"""Isolation milling, measured on a raster: the copper the tool cuts, the shorts it leaves
and whether each was reported, and planning time, per corpus copper layer, beside a plain
offset of the copper by half the cut width (what a naive tool does), in one run.

    python3 bench/bench_mill.py --quick            # a handful of small copper layers
    python3 bench/bench_mill.py                    # every copper layer of the corpus
    python3 bench/bench_mill.py --files 'kicad/*' --tool endmill --diameter 0.3 --passes 2
    python3 bench/bench_mill.py --json /tmp/mill.json --jobs 2 --png /tmp/mill

Copper layers: those bench_ink_union.py takes (`looks_like_copper` on the manifest's
'real' and 'derived' files); --quick: bench_ink.py's six small ones (up to 40 kB). Each file is measured
in a child process (`--timeout` s); a failure costs that file only and is printed.
Numbers are printed, never asserted.

Per layer and tool (the profile's default V-bit unless told):
- ours: `isolate` + `prove` (parts 1 and 2, the swept-area witness left out), timed
  together from the read Program: the planning time the Must-show bounds (5 s), wall
  and CPU (one thread: its CPU time is the wall time on an idle machine; the summary
  judges the CPU time, as six helpers share two cores while this runs). The
  clearance is the proof's: the least distance from any pass to the copper polygons.
- naive: the copper (the same exact geometry) offset by half the cut width, one pass,
  Clipper's round joins at the same arc tolerance, no margin; no shorts reported. Its
  clearance (proof.clearance_nm) shows how far inside half the cut its chords run.
- The raster, at --pitch-um (10 um) pixel centres, over the copper and both tools'
  passes: copper = pixel centres inside the exact copper polygons; deep copper = inside
  the copper shrunk by --allow-um (20 um); swept = pixel centres within half the cut
  width of a pass segment (the tool's disc swept along it, solved exactly per row:
  bench/ink_raster.capsule_spans). "cut" is swept and copper, "deep" swept and deep
  copper (the copper cut beyond the allowance), in um^2 (pixels x pitch^2).
- Shorts left: connected parts (8-connected) of what the tool leaves (not swept) that
  hold two or more copper islands (each island found by the middle pixel of its
  longest raster span; an island with no pixel centre is not counted). "left" adds up
  islands - 1 per part; "unrep" is how many of those joins the reported shorts do not
  explain (the reported pairs, and the pairs that touch by shapely, which are one
  copper, joined by union-find, per part: groups - 1); "alarm" is
  the reported pairs whose islands the raster sees parted (find_shorts takes every gap
  under two first-pass radii; where the gap is barely under the cut, the disc sweeping
  round both pads leaves a sliver thinner than a pixel between them). A board whose raster would pass --max-mpx is measured at a
  coarser pitch, printed in the row.

Pixel centres count on an outline (closed sets, bench/ink_raster.py), so a pass exactly
half the cut off an axis-parallel edge that lies on a row of pixel centres "cuts" that
row: the naive offset's cut is mostly such touching rows (its passes reach at most a
micrometre or two into the copper: its clearance column), none of it beyond the
allowance.
"""

from __future__ import annotations

import argparse
import json
import math
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))
sys.path.insert(0, str(REPO / "tests"))
sys.path.insert(0, str(REPO / "bench"))

from corpus import CORPUS  # noqa: E402

UM2_PER_NM2 = 1e-6
BAND_ROWS = 256


def mill_config(args):
    from galileo_cnc.config.mill import MillConfig

    values = {"passes": args.passes, "overlap_permille": round(args.overlap * 1000)}
    if args.tool == "endmill":
        values.update(tool="endmill", diameter_nm=round(args.diameter * 1e6))
    else:
        values.update(tool="vbit", tip_nm=round(args.tip * 1e6),
                      angle_mdeg=round(args.angle * 1000), cut_depth_nm=round(args.depth * 1e6))
    return MillConfig(**values)


# --------------------------------------------------------------------------- child

def measure(rel: str, args) -> dict:
    from galileo_cnc.plan.ink import clip
    from galileo_cnc.plan.mill.isolate import MILL_TOLERANCE_NM, arc_tolerance_nm, isolate
    from galileo_cnc.plan.mill.proof import clearance_nm, prove
    from galileo_cnc.readers import read_file

    mill = mill_config(args)
    program = read_file(str(CORPUS / rel))
    clock, cpu = time.perf_counter(), time.process_time()
    isolation = isolate(program, mill)
    proof = prove(isolation, swept=False)
    plan_s, plan_cpu_s = time.perf_counter() - clock, time.process_time() - cpu
    if not isolation.islands.parts:
        return {"file": rel, "empty": True}
    clock = time.perf_counter()
    naive = clip.rings_as_arrays(clip.offset(isolation.copper, mill.cut_width_nm // 2,
                                             arc_tolerance_nm(MILL_TOLERANCE_NM)))
    naive_s = time.perf_counter() - clock
    naive_clear = clearance_nm(naive, isolation.islands.rings, mill.cut_width_nm)
    record = {"file": rel, "islands": len(isolation.islands.parts), "plan_s": plan_s,
              "plan_cpu_s": plan_cpu_s, "proof_s": proof.seconds, "steps_s": isolation.seconds,
              "naive_s": naive_s, "clearance_mm": proof.clearance_nm / 1e6,
              "naive_clearance_mm": naive_clear / 1e6,
              "proof": proof.holds, "reported": len(isolation.shorts),
              "cut_width_mm": mill.cut_width_nm / 1e6,
              "shorts_mm": [[s.at_nm[0] / 1e6, s.at_nm[1] / 1e6] for s in isolation.shorts]}
    clock = time.perf_counter()
    raster = Raster(isolation, [isolation.rings, naive], args)
    reported = [s.islands for s in isolation.shorts]
    for name, k, pairs in (("ours", 0, reported), ("naive", 1, [])):
        cut, deep = raster.cut(k)
        left, unreported, alarms = raster.shorts(k, pairs)
        record[name] = {"cut_um2": cut, "deep_um2": deep, "left": left,
                        "unreported": unreported, "alarms": alarms}
    if args.png:
        pictures(raster, isolation, Path(args.png), rel)
    record["pitch_um"] = raster.pitch_nm / 1000
    record["unmeasured_islands"] = raster.unmeasured
    record["raster_s"] = time.perf_counter() - clock
    return record


class Raster:
    """The copper, the deep copper and each tool's swept area on one pixel grid."""

    def __init__(self, isolation, tools: list[list[np.ndarray]], args):
        from galileo_cnc.plan.ink import clip

        self.isolation = isolation
        self.radius_nm = isolation.cut_width_nm / 2
        points = [np.concatenate(rings) for rings in tools if rings] + \
            [np.concatenate(isolation.islands.rings)]
        every = np.concatenate(points)
        box = (*every.min(axis=0), *every.max(axis=0))
        pitch = args.pitch_um * 1000
        while ((box[2] - box[0]) / pitch + 8) * ((box[3] - box[1]) / pitch + 8) > args.max_mpx * 1e6:
            pitch *= 1.25
        self.pitch_nm = pitch
        self.grid = _grid(box, pitch)
        self.copper_rings = isolation.islands.rings
        deep = clip.offset(isolation.copper, -args.allow_um * 1000, isolation.tolerance_nm)
        self.deep_rings = clip.rings_as_arrays(deep)
        self.tools = tools
        self.swept = [self._swept(rings) for rings in tools]
        self._island_pixels()

    # the masks, a band of rows at a time
    def _bands(self):
        for r0 in range(0, self.grid.height, BAND_ROWS):
            yield r0, min(r0 + BAND_ROWS, self.grid.height)

    def _polygon_mask(self, rings, r0: int, r1: int, lows, highs) -> np.ndarray:
        from ink_raster import SpanCanvas, polygon_spans

        band = self.grid.band(r0, r1)
        top, bottom = band.top_nm, band.top_nm - (r1 - r0) * self.pitch_nm
        near = [rings[k] for k in np.flatnonzero((highs >= bottom) & (lows <= top)).tolist()]
        canvas = SpanCanvas(r1 - r0, band.width)
        for spans in polygon_spans(near, band):
            canvas.add(*spans)
        return canvas.mask()

    def _swept(self, rings) -> np.ndarray:
        from ink_raster import SpanCanvas, capsule_spans

        mask = np.zeros((self.grid.height, self.grid.width), dtype=bool)
        if not rings:
            return mask
        a = np.concatenate(rings).astype(np.float64)
        b = np.concatenate([np.roll(ring, -1, axis=0) for ring in rings]).astype(np.float64)
        ua, va = self.grid.u(a[:, 0]), self.grid.v(a[:, 1])
        ub, vb = self.grid.u(b[:, 0]), self.grid.v(b[:, 1])
        r = self.radius_nm / self.pitch_nm
        vlo, vhi = np.minimum(va, vb) - r, np.maximum(va, vb) + r
        for r0, r1 in self._bands():
            take = (vhi >= r0 - 1) & (vlo <= r1)
            canvas = SpanCanvas(r1 - r0, self.grid.width)
            for row, c0, c1 in capsule_spans(ua[take], va[take] - r0, ub[take], vb[take] - r0, r):
                canvas.add(row, c0, c1)
            mask[r0:r1] = canvas.mask()
        return mask

    def cut(self, k: int) -> tuple[float, float]:
        """um^2 of the copper, and of the deep copper, the tool k sweeps."""
        counts = [0, 0]
        for which, rings in enumerate((self.copper_rings, self.deep_rings)):
            lows, highs = _y_bounds(rings)
            for r0, r1 in self._bands():
                mask = self._polygon_mask(rings, r0, r1, lows, highs)
                counts[which] += int(np.count_nonzero(mask & self.swept[k][r0:r1]))
        pixel_um2 = (self.pitch_nm / 1000) ** 2
        return counts[0] * pixel_um2, counts[1] * pixel_um2

    def _island_pixels(self) -> None:
        """One pixel (row, col) inside each island, -1 where no pixel centre is."""
        from ink_raster import polygon_spans

        self.pixel = np.full((len(self.isolation.islands.parts), 2), -1, dtype=np.int64)
        for number, (outer, holes) in enumerate(self.isolation.islands.parts):
            best = None
            for row, c0, c1 in polygon_spans([outer, *holes], self.grid):
                if len(row):
                    k = int(np.argmax(c1 - c0))
                    if c1[k] >= c0[k] and (best is None or c1[k] - c0[k] > best[2] - best[1]):
                        best = (int(row[k]), int(c0[k]), int(c1[k]))
            if best is not None:
                self.pixel[number] = (best[0], (best[1] + best[2]) // 2)
        self.unmeasured = int(np.count_nonzero(self.pixel[:, 0] < 0))

    def shorts(self, k: int, reported: list[tuple[int, int]]) -> tuple[int, int, int]:
        """(islands joined by what tool k leaves, joins the reported pairs do not
        explain, reported pairs the tool separated): module doc."""
        from ink_raster import label_runs, mask_runs

        runs = mask_runs(~self.swept[k])
        labels = label_runs(runs)
        measured = np.flatnonzero(self.pixel[:, 0] >= 0)
        rows, cols = self.pixel[measured, 0], self.pixel[measured, 1]
        keys = runs.keys(runs.start)
        at = np.searchsorted(keys, rows * (runs.width + 3) + cols + 1, "right") - 1
        inside = (at >= 0) & (runs.row[at] == rows) & (runs.end[at] >= cols)
        part = np.full(len(self.pixel), -1, dtype=np.int64)
        part[measured[inside]] = labels[at[inside]]
        # a swept island pixel (a naive cut through a thin island) is a part of its own
        alone = np.flatnonzero(part < 0)
        part[alone] = -1 - alone
        parts = part[measured]
        left = len(parts) - len(np.unique(parts))
        group = np.arange(len(self.pixel))

        def root(n):
            while group[n] != n:
                group[n] = group[group[n]]
                n = group[n]
            return n

        for a, b in reported + self._touching(parts, measured):
            group[root(a)] = root(b)
        roots = np.array([root(n) for n in measured.tolist()], dtype=np.int64)
        unreported = len(np.unique(np.stack([parts, roots], axis=1), axis=0)) - len(np.unique(parts))
        alarms = sum(1 for a, b in reported if part[a] != part[b])
        return left, unreported, alarms


    def _touching(self, parts: np.ndarray, measured: np.ndarray) -> list[tuple[int, int]]:
        """Pairs of islands that touch (shapely: they intersect), in the parts of the
        uncut area that hold more than one island: copper that touches is one island,
        nothing to report."""
        import shapely

        found = []
        for label in np.unique(parts).tolist():
            members = measured[parts == label]
            if len(members) < 2:
                continue
            polygons = [shapely.Polygon(*self.isolation.islands.parts[n]) for n in members.tolist()]
            a, b = shapely.STRtree(polygons).query(polygons, predicate="intersects")
            keep = a < b
            found += list(zip(members[a[keep]].tolist(), members[b[keep]].tolist()))
        return found


def pictures(raster: Raster, isolation, folder: Path, rel: str) -> None:
    """Two PNGs of the layer: the whole of it (every --pitch-um pixel, or every n-th
    to keep it within 1600 px), and a 3 mm window round the first reported short (else
    round the middle) at the raster's pitch, drawn 3 px a pixel. Copper is orange, the
    tool's swept area (ours) grey, copper it sweeps red; reported shorts are ringed red."""
    from PIL import Image, ImageDraw

    folder.mkdir(parents=True, exist_ok=True)
    grid = raster.grid
    copper = np.zeros((grid.height, grid.width), dtype=bool)
    lows, highs = _y_bounds(raster.copper_rings)
    for r0, r1 in raster._bands():
        copper[r0:r1] = raster._polygon_mask(raster.copper_rings, r0, r1, lows, highs)
    swept = raster.swept[0]
    image = np.full((grid.height, grid.width, 3), 255, dtype=np.uint8)
    image[swept] = (150, 150, 160)
    image[copper] = (222, 140, 40)
    image[copper & swept] = (220, 0, 0)
    stem = rel.replace("/", "_")
    shorts = [(float(grid.u(s.at_nm[0])), float(grid.v(s.at_nm[1]))) for s in isolation.shorts]
    stride = max(1, math.ceil(max(grid.width, grid.height) / 1600))
    whole = Image.fromarray(image[::stride, ::stride])
    draw = ImageDraw.Draw(whole)
    for u, v in shorts:
        draw.ellipse([u / stride - 12, v / stride - 12, u / stride + 12, v / stride + 12],
                     outline=(220, 0, 0), width=2)
    whole.save(folder / f"{stem}.png")
    half = int(1.5e6 / raster.pitch_nm)
    cu, cv = (shorts[0] if shorts else (grid.width / 2, grid.height / 2))
    c0, r0 = max(0, int(cu) - half), max(0, int(cv) - half)
    window = Image.fromarray(image[r0:r0 + 2 * half, c0:c0 + 2 * half])
    window = window.resize((window.width * 3, window.height * 3), Image.NEAREST)
    draw = ImageDraw.Draw(window)
    for u, v in shorts:
        x, y = (u - c0) * 3, (v - r0) * 3
        draw.ellipse([x - 30, y - 30, x + 30, y + 30], outline=(220, 0, 0), width=3)
    window.save(folder / f"{stem}.window.png")


def _y_bounds(rings):
    if not rings:
        return np.zeros(0), np.zeros(0)
    return (np.array([ring[:, 1].min() for ring in rings]),
            np.array([ring[:, 1].max() for ring in rings]))


class _PitchGrid:
    """ink_raster.Grid's interface at any pitch (it takes whole dots per mm)."""

    def __init__(self, left_nm: float, top_nm: float, pitch_nm: float, width: int, height: int):
        self.left_nm, self.top_nm, self.pitch_nm = left_nm, top_nm, pitch_nm
        self.width, self.height = width, height
        self.scale = 1.0 / pitch_nm

    def u(self, x_nm):
        return (np.asarray(x_nm, dtype=np.float64) - self.left_nm) * self.scale - 0.5

    def v(self, y_nm):
        return (self.top_nm - np.asarray(y_nm, dtype=np.float64)) * self.scale - 0.5

    def band(self, r0: int, r1: int) -> "_PitchGrid":
        return _PitchGrid(self.left_nm, self.top_nm - r0 * self.pitch_nm, self.pitch_nm,
                          self.width, r1 - r0)


def _grid(box, pitch_nm: float, pad_px: int = 4) -> _PitchGrid:
    left = math.floor(box[0] / pitch_nm) * pitch_nm - pad_px * pitch_nm
    top = math.ceil(box[3] / pitch_nm) * pitch_nm + pad_px * pitch_nm
    width = int(math.ceil((box[2] - left) / pitch_nm)) + pad_px
    height = int(math.ceil((top - box[1]) / pitch_nm)) + pad_px
    return _PitchGrid(left, top, pitch_nm, width, height)


# --------------------------------------------------------------------------- parent

def run_child(rel: str, argv: list[str], timeout: float) -> dict:
    command = [sys.executable, __file__, "--child", rel, *argv]
    try:
        done = subprocess.run(command, capture_output=True, text=True, timeout=timeout)
    except subprocess.TimeoutExpired:
        return {"file": rel, "error": f"timeout after {timeout:g} s"}
    if done.returncode != 0:
        tail = (done.stderr.strip().splitlines() or ["(no output)"])[-1]
        return {"file": rel, "error": tail[:160]}
    return json.loads(done.stdout.strip().splitlines()[-1])


def print_table(records: list[dict], args) -> None:
    print(f"tool: {mill_config(args).describe()}; raster {args.pitch_um:g} um, "
          f"allowance {args.allow_um:g} um")
    head = (f"{'layer':44s} {'isl':>5s} {'plan s':>6s} {'cpu s':>5s} {'clear mm':>8s} | "
            f"{'ours cut':>9s} {'>20um':>6s} {'left':>4s} {'rep':>4s} {'unrep':>5s} "
            f"{'alarm':>5s} | {'clear mm':>8s} {'naive cut':>9s} {'>20um':>6s} {'left':>4s} "
            f"{'unrep':>5s}")
    print(head)
    print("-" * len(head))
    for r in records:
        name = r["file"][-44:]
        if "error" in r:
            print(f"{name:44s} FAILED: {r['error']}")
            continue
        if r.get("empty"):
            print(f"{name:44s} no copper: nothing to isolate")
            continue
        o, n = r["ours"], r["naive"]
        pitch = "" if r["pitch_um"] == args.pitch_um else f"  (raster {r['pitch_um']:.1f} um)"
        print(f"{name:44s} {r['islands']:5d} {r['plan_s']:6.2f} {r['plan_cpu_s']:5.2f} "
              f"{r['clearance_mm']:8.4f} | "
              f"{o['cut_um2']:9.0f} {o['deep_um2']:6.0f} {o['left']:4d} {r['reported']:4d} "
              f"{o['unreported']:5d} {o['alarms']:5d} | {r['naive_clearance_mm']:8.4f} "
              f"{n['cut_um2']:9.0f} {n['deep_um2']:6.0f} "
              f"{n['left']:4d} {n['unreported']:5d}{pitch}")
    done = [r for r in records if "error" not in r and not r.get("empty")]
    empty = sum(1 for r in records if r.get("empty"))
    if not done:
        return
    print("-" * len(head))
    worst = max(done, key=lambda r: r["plan_cpu_s"])
    print(f"{len(done)} layers ({len(records) - len(done) - empty} failed, {empty} without "
          f"copper): "
          f"ours: copper cut {sum(r['ours']['cut_um2'] for r in done):.0f} um2, beyond "
          f"{args.allow_um:g} um {sum(r['ours']['deep_um2'] for r in done):.0f} um2; shorts left "
          f"{sum(r['ours']['left'] for r in done)}, unreported "
          f"{sum(r['ours']['unreported'] for r in done)}, reported "
          f"{sum(r['reported'] for r in done)} ({sum(r['ours']['alarms'] for r in done)} the "
          f"tool did separate); proof holds on {sum(r['proof'] for r in done)}; planning "
          f"at most {worst['plan_cpu_s']:.2f} s CPU, {worst['plan_s']:.2f} s wall ({worst['file']}); "
          f"{sum(r['plan_cpu_s'] > 5 for r in done)} layers over 5 s CPU")
    print(f"naive: copper cut {sum(r['naive']['cut_um2'] for r in done):.0f} um2, beyond "
          f"{args.allow_um:g} um {sum(r['naive']['deep_um2'] for r in done):.0f} um2; shorts "
          f"left {sum(r['naive']['left'] for r in done)}, none reported")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--quick", action="store_true", help="six small copper layers")
    ap.add_argument("--files", help="only layers matching this glob")
    ap.add_argument("--limit", type=int)
    ap.add_argument("--tool", choices=("vbit", "endmill"), default="vbit")
    ap.add_argument("--tip", type=float, default=0.1, help="V-bit tip, mm")
    ap.add_argument("--angle", type=float, default=30.0, help="V-bit angle, degrees")
    ap.add_argument("--depth", type=float, default=0.1, help="cut depth, mm")
    ap.add_argument("--diameter", type=float, default=0.8, help="end mill, mm")
    ap.add_argument("--passes", type=int, default=1)
    ap.add_argument("--overlap", type=float, default=0.25)
    ap.add_argument("--pitch-um", type=float, default=10.0)
    ap.add_argument("--allow-um", type=float, default=20.0)
    ap.add_argument("--max-mpx", type=float, default=150.0)
    ap.add_argument("--timeout", type=float, default=600.0)
    ap.add_argument("--jobs", type=int, default=1)
    ap.add_argument("--json", help="write the records here (and each as it ends to "
                    "JSON.lines)")
    ap.add_argument("--table", help="print the table of a JSON.lines file and stop")
    ap.add_argument("--png", help="write pictures of each layer to this folder")
    ap.add_argument("--child", help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.child:
        print(json.dumps(measure(args.child, args)))
        return
    if args.table:
        print_table([json.loads(line) for line in Path(args.table).read_text().splitlines()],
                    args)
        return
    argv = [a for a in sys.argv[1:] if a not in ("--quick",)]
    for option in ("--json", "--files", "--limit", "--jobs", "--timeout"):  # the parent's
        if option in argv:
            at = argv.index(option)
            del argv[at:at + 2]
    from bench_ink import copper_files

    files = copper_files(args)
    from concurrent.futures import ThreadPoolExecutor

    def one(rel: str) -> dict:
        record = run_child(rel, argv, args.timeout)
        # a line per layer as it ends: a long run shows where it is
        said = record.get("error") or ("no copper" if record.get("empty")
                                       else f"plan {record['plan_s']:.2f} s")
        print(f"{rel}: {said}", file=sys.stderr, flush=True)
        if args.json:                     # kept as they end: a stopped run keeps its layers
            with open(f"{args.json}.lines", "a") as lines:
                lines.write(json.dumps(record) + "\n")
        return record

    with ThreadPoolExecutor(max_workers=max(1, args.jobs)) as pool:
        records = list(pool.map(one, files))
    print_table(records, args)
    if args.json:
        Path(args.json).write_text(json.dumps(records, indent=1))


if __name__ == "__main__":
    main()
