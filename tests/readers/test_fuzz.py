"""A seeded sample of the reader fuzz campaign (bench/bench_fuzz.py runs the full one).

Each mutant either reads (with every coordinate inside the reader's bound) or raises a
GalileoError that names file:line. The op limit is lowered for the sample so refusals
of huge expansions come quickly; the campaign runs with the real limits, in children
with a memory limit and a timeout. A failing seed is reproduced with
`GALILEO_MAX_OPS=200000 GALILEO_MAX_BLOCK_ENTITIES=20000 python3 bench/bench_fuzz.py
--show SEED --ci` (a drill-only seed with `--formats drill`).
"""

import numpy as np
import pytest

import mutants
from galileo_cnc.errors import GalileoError
from galileo_cnc.program.ops import I, J, X, Y
from galileo_cnc.readers import read_drill, read_file

SEEDS = range(200)
DRILL_SEEDS = range(10_000, 10_060)       # drill-file mutants only
BOUNDS_NM = {"gerber": 10**10, "gcode": 10**12, "dxf": 10**15, "drill": 10**10}


@pytest.fixture(scope="module")
def pools():
    loaded = mutants.load_pools(max_gerber=30_000, max_dxf=40_000)
    if not loaded.gerber or not loaded.dxf:
        pytest.skip(f"no corpus files at {mutants.GERBER_CORPUS} or {mutants.DXF_CORPUS}")
    return loaded


@pytest.mark.parametrize("seed, formats", [(seed, mutants.FORMATS) for seed in SEEDS]
                         + [(seed, ("drill",)) for seed in DRILL_SEEDS])
def test_a_mutant_reads_or_gives_a_positioned_error(seed, formats, pools, tmp_path, monkeypatch):
    monkeypatch.setenv("GALILEO_MAX_OPS", "200000")
    monkeypatch.setenv("GALILEO_MAX_BLOCK_ENTITIES", "20000")
    mutant = mutants.mutant(seed, pools, ci=True, formats=formats)
    path = tmp_path / f"mutant-{seed}{mutant.extension}"
    path.write_bytes(mutant.data)
    what = f"seed {seed}: {mutant.fmt} {mutant.kind} of {mutant.source} ({mutant.how})"
    try:
        if mutant.fmt == "drill":
            drill = read_drill(path)
            values = [v for h in drill.holes for v in (h.x_nm, h.y_nm)] + \
                [v for s in drill.slots for v in (s.x0_nm, s.y0_nm, s.x1_nm, s.y1_nm, s.cx_nm, s.cy_nm)]
            assert max(map(abs, values), default=0) <= BOUNDS_NM["drill"], what
            return
        program = read_file(path)
    except GalileoError as error:
        pos = getattr(error, "pos", None)
        assert pos is not None and pos.line >= 1, f"{what}: no position: {error}"
        assert f"{path}:{pos.line}" in str(error), f"{what}: {error}"
        return
    if len(program.table):
        biggest = int(np.abs(program.table[:, [X, Y, I, J]]).max())
        assert biggest <= BOUNDS_NM[program.format], f"{what}: a coordinate of {biggest} nm"


def test_the_same_seed_gives_the_same_mutant(pools):
    first, again = mutants.mutant(1234, pools), mutants.mutant(1234, pools)
    assert (first.fmt, first.kind, first.source, first.data) == \
        (again.fmt, again.kind, again.source, again.data)
    kinds = {mutants.mutant(seed, pools, ci=True).kind for seed in range(60)}
    assert kinds == set(mutants.KINDS)
