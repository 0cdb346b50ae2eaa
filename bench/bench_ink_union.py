"""Inking the copper: pyclipper (integer Clipper) against shapely 2 (GEOS) on every
copper layer of the corpus, in one run.

    python3 bench/bench_ink_union.py              # every copper layer, all backends
    python3 bench/bench_ink_union.py --quick      # copper layers up to 100 kB
    python3 bench/bench_ink_union.py --backends clipper,shapely --tolerance 1000

Backends (galileo_cnc/plan/ink/backends.py):
  clipper        pyclipper, integer coordinates (what the ink uses, docs/ink.md)
  shapely        shapely 2 / GEOS OverlayNG with grid_size=1: results snapped to the nm grid
  shapely-float  shapely 2 without a grid: float results (intersections are not integers)

Copper layers: the manifest has no column for the layer's function, so the files are
the 'real' and 'derived' ones that galileo_cnc.plan.ink.copper.looks_like_copper
takes for copper (the X2 %TF.FileFunction where there is one, else the name and the
header comments).

Each backend runs in its own child process over the same files, one after another.
Per file: the Gerber is read first (not timed), then `dark_geometry` is timed: "build"
is making the polygons of every object and handing them to the library, "bool" the
unions and differences. Peak memory is the child's peak RSS during that call above
its RSS before it (freed heap is returned with malloc_trim and the kernel's
high-water mark is reset per file through /proc/self/clear_refs), so the C++
allocations of GEOS and Clipper count too, which tracemalloc would not see. "ok"
is v when shapely's is_valid holds for the result (pyclipper's converted through
its PolyTree), and i when every vertex is an integer nm. The children write each
result as WKB; the parent then compares every backend with the first one: relative
area difference and the area of the symmetric difference. Numbers are printed,
never asserted.
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))
sys.path.insert(0, str(REPO / "tests"))

from corpus import CORPUS, manifest

MB = 2 ** 20
MM2 = 1e12  # nm^2 per mm^2


def copper_layers(max_bytes: int | None = None) -> list[str]:
    from galileo_cnc.plan.ink.copper import looks_like_copper

    found = []
    for row in manifest():
        if row["kind"] not in ("real", "derived"):
            continue
        if max_bytes is not None and int(row["bytes"]) > max_bytes:
            continue
        head = (CORPUS / row["path"]).read_bytes()[:4000].decode("latin-1")
        if looks_like_copper(row["path"], head):
            found.append(row["path"])
    return found


# --------------------------------------------------------------------------- child


def _status(key: str) -> int:
    with open("/proc/self/status") as status:
        for line in status:
            if line.startswith(key):
                return int(line.split()[1]) * 1024
    return 0


def _reset_peak() -> bool:
    """Give freed heap back to the system, then restart the kernel's peak-RSS count,
    so that each file's peak is its own (not hidden in memory a former file freed)."""
    try:
        import ctypes

        ctypes.CDLL("libc.so.6").malloc_trim(0)
    except (OSError, AttributeError):
        pass
    try:
        with open("/proc/self/clear_refs", "w") as handle:
            handle.write("5")
        return True
    except OSError:
        return False


def child(backend_name: str, files: list[str], tolerance: int, out: Path) -> None:
    import numpy as np
    import shapely

    from galileo_cnc.plan.ink import dark_geometry
    from galileo_cnc.plan.ink.backends import make_backend
    from galileo_cnc.readers import read_file

    backend = make_backend(backend_name)
    for index, path in enumerate(files):
        record = {"path": path}
        try:
            program = read_file(CORPUS / path)
            resettable = _reset_peak()
            before = _status("VmRSS:")
            start = time.perf_counter()
            image = dark_geometry(program, tolerance_nm=tolerance, backend=backend)
            seconds = time.perf_counter() - start
            peak = max(0, _status("VmHWM:") - before) if resettable else None
            geometry = image.to_shapely()
            coordinates = shapely.get_coordinates(geometry)
            record.update(
                seconds=seconds, build=image.stats["shapes_s"], bool=image.stats["boolean_s"],
                peak=peak, objects=image.stats["objects"], runs=image.stats["runs"],
                clear_runs=image.stats["clear_runs"], area=image.area_nm2(),
                vertices=image.vertex_count(),
                polygons=int(shapely.get_num_geometries(geometry)),
                valid=bool(shapely.is_valid(geometry)),
                integer=bool((coordinates == np.rint(coordinates)).all()))
            (out / f"{index}.wkb").write_bytes(shapely.to_wkb(geometry))
        except Exception as problem:  # noqa: BLE001 (a failure is a result too)
            record["error"] = f"{type(problem).__name__}: {problem}"[:200]
        print(json.dumps(record), flush=True)


# --------------------------------------------------------------------------- parent


def run_backend(name: str, files: list[str], tolerance: int, out: Path) -> list[dict]:
    out.mkdir(parents=True, exist_ok=True)
    listing = out / "files.json"
    listing.write_text(json.dumps(files))
    command = [sys.executable, __file__, "--child", name, "--files", str(listing),
               "--tolerance", str(tolerance), "--out", str(out)]
    started = time.perf_counter()
    result = subprocess.run(command, capture_output=True, text=True, check=False)
    records = [json.loads(line) for line in result.stdout.splitlines() if line.startswith("{")]
    if result.returncode or len(records) != len(files):
        sys.stderr.write(result.stderr[-3000:])
        raise SystemExit(f"{name}: child failed after {len(records)} of {len(files)} files")
    print(f"  {name}: {time.perf_counter() - started:.1f} s wall", file=sys.stderr)
    return records


def compare(reference: Path, other: Path, index: int) -> float | None:
    """Area (nm^2) of the symmetric difference of two results, None if either is missing."""
    import shapely

    a_path, b_path = reference / f"{index}.wkb", other / f"{index}.wkb"
    if not (a_path.exists() and b_path.exists()):
        return None
    a, b = shapely.from_wkb(a_path.read_bytes()), shapely.from_wkb(b_path.read_bytes())
    try:
        return float(shapely.symmetric_difference(a, b).area)
    except shapely.errors.GEOSException:
        return float(shapely.symmetric_difference(shapely.make_valid(a), shapely.make_valid(b),
                                                  grid_size=1).area)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="copper layers up to 100 kB only")
    ap.add_argument("--backends", default="clipper,shapely,shapely-float",
                    help="comma-separated; the first is the reference for the comparison")
    ap.add_argument("--tolerance", type=int, default=None, help="chord tolerance in nm")
    ap.add_argument("--limit", type=int, default=None, help="first N files only")
    ap.add_argument("--child", help=argparse.SUPPRESS)
    ap.add_argument("--files", help=argparse.SUPPRESS)
    ap.add_argument("--out", help=argparse.SUPPRESS)
    args = ap.parse_args()
    from galileo_cnc.plan.ink import DEFAULT_TOLERANCE_NM

    tolerance = args.tolerance or DEFAULT_TOLERANCE_NM
    if args.child:
        child(args.child, json.loads(Path(args.files).read_text()), tolerance, Path(args.out))
        return

    files = copper_layers(100_000 if args.quick else None)[: args.limit]
    sizes = {path: (CORPUS / path).stat().st_size for path in files}
    names = args.backends.split(",")
    print(f"{len(files)} copper layers, {sum(sizes.values()) / MB:.1f} MB, tolerance "
          f"{tolerance} nm, backends {', '.join(names)}", file=sys.stderr)
    import pyclipper
    import shapely

    versions = {"clipper": f"pyclipper {pyclipper.__version__}",
                "shapely": f"shapely {shapely.__version__} (GEOS {shapely.geos_version_string})"}
    with tempfile.TemporaryDirectory() as scratch:
        results = {name: run_backend(name, files, tolerance, Path(scratch) / name)
                   for name in names}
        symdiff = {name: [compare(Path(scratch) / names[0], Path(scratch) / name, k)
                          for k in range(len(files))] for name in names[1:]}
    report(files, sizes, names, results, symdiff, versions, tolerance)


def report(files, sizes, names, results, symdiff, versions, tolerance) -> None:
    ref = names[0]
    head = f"{'file':44} {'kB':>6} {'objects':>7} {'runs':>5}"
    for name in names:
        head += f" | {name[:14] + ' s':>16} {'MB':>5} ok"
    for name in names[1:]:
        head += f" | {('d' + name)[:9]:>9} {'symd mm2':>9}"
    print(head)
    print("-" * len(head))
    for k, path in enumerate(files):
        first = results[ref][k]
        line = f"{path[-44:]:44} {sizes[path] / 1000:6.0f} {first.get('objects', 0):7d} " \
               f"{first.get('runs', 0):5d}"
        for name in names:
            r = results[name][k]
            if "error" in r:
                line += f" | {'ERROR':>16} {'':>5}   "
                continue
            ok = ("v" if r["valid"] else "!") + ("i" if r["integer"] else "f")
            peak = f"{r['peak'] / MB:5.0f}" if r["peak"] is not None else "    ?"
            line += f" | {r['seconds']:16.3f} {peak} {ok}"
        for name in names[1:]:
            a, b = results[ref][k], results[name][k]
            if "error" in a or "error" in b or symdiff[name][k] is None:
                line += f" | {'-':>9} {'-':>9}"
                continue
            relative = (b["area"] - a["area"]) / a["area"] if a["area"] else 0.0
            line += f" | {relative:9.1e} {symdiff[name][k] / MM2:9.2e}"
        print(line)
    print()
    print(f"tolerance {tolerance} nm; 'ok': v = valid (shapely is_valid), ! = invalid; "
          f"i = integer vertices, f = float")
    print(f"{'backend':14} {'total s':>8} {'build s':>8} {'bool s':>8} {'max MB':>7} "
          f"{'sum MB':>7} {'valid':>7} {'integer':>8} {'errors':>6} {'vertices':>10}  version")
    for name in names:
        rows = [r for r in results[name] if "error" not in r]
        peaks = [r["peak"] for r in rows if r["peak"] is not None]
        version = versions.get(name.split("-")[0], "")
        print(f"{name:14} {sum(r['seconds'] for r in rows):8.2f} "
              f"{sum(r['build'] for r in rows):8.2f} {sum(r['bool'] for r in rows):8.2f} "
              f"{max(peaks, default=0) / MB:7.0f} {sum(peaks) / MB:7.0f} "
              f"{sum(r['valid'] for r in rows):3d}/{len(rows):<3d} "
              f"{sum(r['integer'] for r in rows):4d}/{len(rows):<3d} "
              f"{len(results[name]) - len(rows):6d} "
              f"{sum(r['vertices'] for r in rows):10d}  {version}")
        for r in results[name]:
            if "error" in r:
                print(f"    {r['path']}: {r['error']}")
    for name in names[1:]:
        pairs = [(a, b, s) for a, b, s in zip(results[ref], results[name], symdiff[name])
                 if "error" not in a and "error" not in b and s is not None and a["area"]]
        if not pairs:
            continue
        worst = max(pairs, key=lambda p: abs(p[1]["area"] - p[0]["area"]) / p[0]["area"])
        worst_sym = max(pairs, key=lambda p: p[2] / p[0]["area"])
        print(f"{name} vs {ref}: total area {sum(p[1]['area'] for p in pairs) / MM2:.6f} vs "
              f"{sum(p[0]['area'] for p in pairs) / MM2:.6f} mm2; largest relative area "
              f"difference {abs(worst[1]['area'] - worst[0]['area']) / worst[0]['area']:.1e} "
              f"({worst[0]['path']}); symmetric difference total "
              f"{sum(p[2] for p in pairs) / MM2:.3e} mm2, largest "
              f"{worst_sym[2] / MM2:.3e} mm2 = {worst_sym[2] / worst_sym[0]['area']:.1e} of the "
              f"area ({worst_sym[0]['path']})")


if __name__ == "__main__":
    main()
