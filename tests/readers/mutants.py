"""Seeded mutants of real files: the reader fuzz campaign's generator.

`bench/bench_fuzz.py` runs thousands of them in children with a memory limit and a
timeout; `tests/readers/test_fuzz.py` runs a small seeded sample in CI. One integer
seed gives one mutant (format, kind, source file and bytes), so every failure is
reproduced by its seed alone:

    python3 bench/bench_fuzz.py --show SEED       # run it here, with the traceback
    python3 bench/bench_fuzz.py --write SEED DIR  # write the mutant file

Sources: small files of the Gerber and DXF corpus (tests/corpus.py; read in place), the
Excellon drill and route files of its drill/ folder (format "drill", read with
read_drill), and G-code written from small Gerber corpus files plus the sample drawing
and a few hand-written files that use the rest of the dialect.

Kinds of mutation:
- flip: bytes flipped or replaced by characters that mean something to a parser;
- truncate: the file cut short (or a piece cut out of the middle);
- splice: spans deleted, duplicated or moved;
- huge-number: numbers of 13 to thousands of digits, G/M/D words of hundreds of
  digits, exponents, a run of statements with huge coordinates (wrap-around);
- deep-nesting: nested macro expressions, nested %AB blocks, macros that square a
  value again and again, nested comments, DXF blocks inserting blocks;
- huge-repeat: %SR with huge counts, statements repeated up to millions of times,
  MINSERT with huge counts;
- oddity: the odd things real files hold (a stray '*' in %AD, %IF of a missing
  file, a region open at M02, coordinates before %FS, NUL padding, a BOM, CRLF ...);
- binary: random bytes put in, appended, or a whole file of them.
"""

from __future__ import annotations

import random
import re
import sys
from dataclasses import dataclass, field
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]
if str(REPO / "tests") not in sys.path:  # bench/bench_fuzz.py puts only tests/readers there
    sys.path.append(str(REPO / "tests"))
from corpus import DXF_CORPUS, GERBER_CORPUS  # noqa: E402

KINDS = ("flip", "truncate", "splice", "huge-number", "deep-nesting", "huge-repeat", "oddity",
         "binary")
FORMATS = ("gerber", "gcode", "dxf", "drill")
EXTENSIONS = {"gerber": ".gbr", "gcode": ".nc", "dxf": ".dxf", "drill": ".drl"}


@dataclass(frozen=True)
class Mutant:
    seed: int
    fmt: str
    kind: str
    source: str
    data: bytes
    how: str  # what was done, for the failure list

    @property
    def extension(self) -> str:
        suffix = Path(self.source).suffix
        return suffix if suffix and len(suffix) <= 5 else EXTENSIONS[self.fmt]


@dataclass
class Pools:
    gerber: list[tuple[str, bytes]]
    gcode: list[tuple[str, bytes]]
    dxf: list[tuple[str, bytes]]
    drill: list[tuple[str, bytes]] = field(default_factory=list)

    def of(self, fmt: str) -> list[tuple[str, bytes]]:
        return getattr(self, fmt)


def _manifest(corpus: Path) -> list[dict]:
    import csv

    path = corpus / "MANIFEST.tsv"
    if not path.exists():
        return []
    with open(path, newline="") as handle:
        return list(csv.DictReader(handle, delimiter="\t"))


_HAND_GCODE = [
    ("hand/arcs.nc", b"G21 G90\nG0 X0 Y0\nM3\nG2 X10 Y0 R5\nG3 X0 Y0 I-5 J0\nG2 X0 Y0 I5 J0\n"
                     b"G91\nG1 X1 Y1\nG90\nM5\nM2\n"),
    ("hand/pens.nc", b"%\n(pen heights)\nG21\nG0 Z5\nG0 X1 Y1\nG1 Z-1 F300\nG1 X5\nG0 Z5\n"
                     b"T2 M6\nG4 P250\nG92 X0 Y0\nG1 Z-1\nG1 X3 Y3\nG28\nM30\n%\n"),
    ("hand/inch.nc", b"N10 G20 G90 G17\nN20 G0 X0.5 Y0.5\nN30 M3\nN40 G1 X1.25 Y0.5 F12\n"
                     b"N50 G3 X1.25 Y1.5 R0.5\nN60 G90.1 G2 X1.25 Y0.5 I1.25 J1.0\nN70 M5\n"
                     b"N80 M2\n"),
    ("hand/checksum.nc", b"N1 G21*21\nN2 G90*18\nN3 G1 X10 Y10 F600*30\nN4 M2*73\n"),
]


def load_pools(max_gerber: int = 120_000, max_dxf: int = 260_000) -> Pools:
    """Small corpus files (read in place) and the G-code sources."""
    gerber: list[tuple[str, bytes]] = []
    drill: list[tuple[str, bytes]] = []
    for row in _manifest(GERBER_CORPUS):
        if row["kind"] in ("real", "synthetic", "derived", "invalid") and \
                int(row["bytes"]) <= max_gerber:
            gerber.append((row["path"], (GERBER_CORPUS / row["path"]).read_bytes()))
        elif row["kind"] == "drill" and (GERBER_CORPUS / row["path"]).is_file():
            drill.append((row["path"], (GERBER_CORPUS / row["path"]).read_bytes()))
    dxf: list[tuple[str, bytes]] = []
    for row in _manifest(DXF_CORPUS):
        if int(row["bytes"]) <= max_dxf:
            dxf.append((row["path"], (DXF_CORPUS / row["path"]).read_bytes()))
    gcode = [("samples/square-and-circle.nc", (REPO / "samples" / "square-and-circle.nc").read_bytes())]
    gcode += _HAND_GCODE
    gcode += _gcode_from_gerber([item for item in gerber if len(item[1]) <= 30_000][::9][:24])
    return Pools(gerber, gcode, dxf, drill)


def _gcode_from_gerber(sources) -> list[tuple[str, bytes]]:
    from galileo_cnc.errors import GalileoError
    from galileo_cnc.program.ops import KIND, OpKind
    from galileo_cnc.readers.gcode import write_gcode
    from galileo_cnc.readers.gerber import read_gerber

    drawable = [int(k) for k in (OpKind.MOVE, OpKind.LINE, OpKind.ARC_CW, OpKind.ARC_CCW,
                                 OpKind.PEN_UP, OpKind.PEN_DOWN, OpKind.SELECT, OpKind.DWELL,
                                 OpKind.FEED)]
    out = []
    for name, data in sources:
        try:
            program = read_gerber(name, data.decode("utf-8", "replace"))
        except GalileoError:
            continue
        import numpy as np

        program.table = program.table[np.isin(program.table[:, KIND], drawable)]
        try:
            out.append((f"from-gerber/{name}.nc", write_gcode(program).encode()))
        except GalileoError:
            continue
    return out


# ---------------------------------------------------------------------- mutation

def mutant(seed: int, pools: Pools, ci: bool = False,
           formats: tuple[str, ...] = FORMATS) -> Mutant:
    """The mutant of `seed` among `formats` (those with files in `pools`). With ci, sizes
    stay small (the CI sample runs in-process)."""
    rng = random.Random(seed)
    formats = tuple(f for f in formats if pools.of(f)) or ("gcode",)
    fmt = formats[rng.randrange(len(formats))]
    kind = KINDS[rng.randrange(len(KINDS))]
    pool = pools.of(fmt)
    source, data = pool[rng.randrange(len(pool))]
    data, how = _MUTATORS[kind](rng, data, fmt, ci)
    return Mutant(seed, fmt, kind, source, data, how)


_INTERESTING = b"%*XYIJDGM0123456789-+.,()$\n\r \t;x/=ABEFLNOPRST\x00\xff"


def _flip(rng, data, fmt, ci):
    if not data:
        return b"%", "empty -> '%'"
    out = bytearray(data)
    count = rng.choice((1, 1, 2, 4, 8, 32))
    for _ in range(count):
        at = rng.randrange(len(out))
        if rng.random() < 0.4:
            out[at] ^= 1 << rng.randrange(8)
        else:
            out[at] = _INTERESTING[rng.randrange(len(_INTERESTING))]
    return bytes(out), f"{count} bytes flipped"


def _truncate(rng, data, fmt, ci):
    if len(data) < 2:
        return b"", "emptied"
    at = rng.randrange(len(data))
    if rng.random() < 0.7:
        return data[:at], f"cut at byte {at}"
    length = rng.randrange(1, max(2, len(data) // 4))
    return data[:at] + data[at + length:], f"{length} bytes cut at {at}"


def _splice(rng, data, fmt, ci):
    out = data
    steps = rng.randint(1, 4)
    for _ in range(steps):
        if not out:
            break
        at = rng.randrange(len(out))
        length = rng.randint(1, 200)
        action = rng.randrange(4)
        if action == 0:
            out = out[:at] + out[at + length:]
        elif action == 1:
            out = out[:at] + out[at:at + length] * rng.randint(2, 20) + out[at + length:]
        elif action == 2:
            other = rng.randrange(len(out))
            out = out[:at] + out[other:other + length] + out[at:]
        else:
            lines = out.split(b"\n")
            i, j = rng.randrange(len(lines)), rng.randrange(len(lines))
            lines[i], lines[j] = lines[j], lines[i]
            out = b"\n".join(lines)
    return out, f"{steps} splices"


_NUMBER = re.compile(rb"[-+]?\d+(?:\.\d*)?")


def _huge_digits(rng, ci) -> bytes:
    size = rng.choice((13, 19, 20, 25, 40, 100, 400) if ci else (13, 19, 20, 25, 40, 100, 400,
                                                                   4400, 20_000, 200_000))
    body = rng.choice((b"9", b"1", b"7")) * size
    roll = rng.random()
    if roll < 0.2:
        body = b"1" + b"0" * size
    elif roll < 0.3:
        body = b"0." + b"0" * size + b"1"
    elif roll < 0.4:
        body = body + b"." + body
    return (b"-" if rng.random() < 0.3 else b"") + body


def _huge_number(rng, data, fmt, ci):
    numbers = list(_NUMBER.finditer(data))
    if not numbers:
        return data + _huge_digits(rng, ci), "huge number appended"
    roll = rng.random()
    if roll < 0.25 and fmt in ("gerber", "gcode", "drill"):
        # A run of 40 to 200 coordinate statements, all with huge values.
        words = list(re.finditer(rb"([XYIJ])([-+]?\d+(?:\.\d*)?)", data))
        if words:
            start = rng.randrange(len(words))
            digits = rng.choice((12, 12, 13, 18, 19)) if fmt in ("gerber", "drill") \
                else rng.choice((9, 12, 13))
            chosen = words[start:start + rng.randint(80, 400)]
            out, last = [], 0
            for m in chosen:
                value = str(rng.randrange(10 ** (digits - 1), 10 ** digits)).encode()
                if fmt == "gcode" and rng.random() < 0.5:
                    value += b".5"
                out += [data[last:m.start(2)], b"-" if rng.random() < 0.5 else b"", value]
                last = m.end()
            out.append(data[last:])
            return b"".join(out), f"{len(chosen)} coordinates with {digits} digits"
    if roll < 0.45:
        # A G, M or D word (or a DXF group code) of hundreds of digits.
        letters = list(re.finditer(rb"(?m)(?:[GMDNTgmd](\d+))|^\s*(\d+)\s*$", data))
        if letters:
            m = letters[rng.randrange(len(letters))]
            group = 1 if m.group(1) is not None else 2
            digits = b"0" * rng.choice((100, 300, 1000)) + m.group(group) if rng.random() < 0.5 \
                else b"9" * rng.choice((20, 300, 5000))
            return data[:m.start(group)] + digits + data[m.end(group):], \
                f"code word with {len(digits)} digits"
    count = rng.choice((1, 1, 3, 10))
    out = data
    for _ in range(count):
        numbers = list(_NUMBER.finditer(out))
        m = numbers[rng.randrange(len(numbers))]
        if fmt == "dxf" and rng.random() < 0.4:
            replacement = rng.choice((b"1e308", b"-1e308", b"1e400", b"inf", b"nan", b"-nan",
                                      b"1e30", b"3.4e38", b"1e-320", b"123456789012345678901"))
        elif rng.random() < 0.15:
            replacement = m.group() + rng.choice((b"E30", b"e-30", b"E400", b"e99999"))
        else:
            replacement = _huge_digits(rng, ci)
        out = out[:m.start()] + replacement + out[m.end():]
    return out, f"{count} numbers made huge"


def _after_header(data: bytes) -> int:
    """Where statements can be put in a Gerber file: after its %MO (or %FS), else 0."""
    for marker in (b"%MO", b"%FS"):
        at = data.find(marker)
        if at >= 0:
            end = data.find(b"%", at + 1)
            if end >= 0:
                return end + 1
    return 0


def _before_end(data: bytes) -> int:
    at = data.rfind(b"M02")
    return at if at >= 0 else len(data)


def _deep_nesting(rng, data, fmt, ci):
    big = not ci
    depth = rng.choice((20, 200, 2000, 50_000) if big else (20, 200, 2000))
    if fmt == "gerber":
        roll = rng.randrange(5)
        head = _after_header(data)
        if roll == 0:
            expression = b"(" * depth + b"1" + b")" * depth
            insert = b"%AMDEEP*1,1," + expression + b",0,0*%\n%ADD990DEEP*%\n"
            how = f"macro expression {depth} parentheses deep"
        elif roll == 1:
            insert = b"%AMNEG*1,1," + b"-" * depth + b"1,0,0*%\n%ADD991NEG*%\n"
            how = f"macro expression with {depth} unary minus"
        elif roll == 2:
            steps = rng.choice((10, 40, 200))
            body = b"$1=" + rng.choice((b"10", b"1.5", b"0.7", b"3")) + b"*"
            body += b"".join(b"$%d=$%dx$%d*" % (k + 1, k, k) for k in range(1, steps))
            insert = b"%AMSQ*" + body + b"1,1,$" + str(steps).encode() + b",0,0*%\n%ADD992SQ*%\n"
            how = f"macro squaring a value {steps} times"
        elif roll == 3:
            levels = rng.choice((3, 8, 12, 40) if big else (3, 5, 8))
            flashes = rng.choice((2, 10, 30))
            parts = [b"%ADD10C,0.1*%\n%ABD100*%\nD10*\nX0Y0D03*\n%AB*%\n"]
            for level in range(1, levels):
                parts.append(b"%%ABD%d*%%\nD%d*\n" % (100 + level, 99 + level))
                parts += [b"X%dY0D03*\n" % (k * 10) for k in range(flashes)]
                parts.append(b"%AB*%\n")
            parts.append(b"D%d*\nX0Y0D03*\n" % (99 + levels))
            insert = b"".join(parts)
            how = f"%AB blocks {levels} deep, {flashes} flashes each"
        else:
            insert = b"%ABD900*%\n" * min(depth, 5000) + b"X0Y0D02*\n" + b"%AB*%\n" * min(depth, 5000)
            how = f"{min(depth, 5000)} nested %AB openings"
        return data[:head] + insert + data[head:], how
    if fmt == "gcode":
        roll = rng.randrange(3)
        if roll == 0:
            line = b"G1 X1 (" + b"(" * depth + b")" * depth + b") Y1\n"
            how = f"comment with {depth} nested parentheses"
        elif roll == 1:
            line = b"G1" + b" X1" * depth + b"\n"
            how = f"a line of {depth} X words"
        else:
            line = b"(" * depth + b"\n"
            how = f"{depth} '(' on one line"
        at = data.find(b"\n", rng.randrange(max(1, len(data)))) + 1
        return data[:at] + line + data[at:], how
    if fmt == "drill":
        roll = rng.randrange(3)
        if roll == 0:
            line = b"X1Y1" + b"G85X2Y2" * depth + b"\n"
            how = f"a line of {depth} G85 slots"
        elif roll == 1:
            line = b"M48\n" * depth + b"T1C0.1\n" + b"%\n" * depth
            how = f"{depth} headers opened"
        else:
            line = b";" + b"(" * depth + b"\nX" + b"+" * depth + b"1\n"
            how = f"{depth} signs on one number"
        at = data.find(b"\n", rng.randrange(max(1, len(data)))) + 1
        return data[:at] + line + data[at:], how
    return _dxf_nested_blocks(rng, depth, ci), f"DXF blocks nested {depth} deep"


def _dxf_pairs(*pairs) -> bytes:
    return b"".join(b"%d\n%s\n" % (code, value if isinstance(value, bytes) else str(value).encode())
                    for code, value in pairs)


def _dxf_nested_blocks(rng, depth, ci, columns=1, rows=1) -> bytes:
    """A DXF whose block k inserts block k-1 (columns x rows times); the last may insert itself."""
    levels = min(depth, 300 if ci else 3000)
    cyclic = rng.random() < 0.3
    out = [_dxf_pairs((0, b"SECTION"), (2, b"BLOCKS"))]
    for k in range(levels):
        out.append(_dxf_pairs((0, b"BLOCK"), (8, 0), (2, f"B{k}"), (70, 0), (10, 0), (20, 0), (30, 0)))
        if k == 0:
            out.append(_dxf_pairs((0, b"LINE"), (8, 0), (10, 0), (20, 0), (30, 0), (11, 1), (21, 1),
                                  (31, 0)))
            if cyclic:
                out.append(_dxf_pairs((0, b"INSERT"), (8, 0), (2, f"B{levels - 1}"), (10, 1),
                                      (20, 1), (30, 0)))
        else:
            out.append(_dxf_pairs((0, b"INSERT"), (8, 0), (2, f"B{k - 1}"), (10, 1), (20, 0),
                                  (30, 0), (70, columns), (71, rows), (44, 2), (45, 2)))
        out.append(_dxf_pairs((0, b"ENDBLK"), (8, 0)))
    out.append(_dxf_pairs((0, b"ENDSEC"), (0, b"SECTION"), (2, b"ENTITIES"), (0, b"INSERT"), (8, 0),
                          (2, f"B{levels - 1}"), (10, 0), (20, 0), (30, 0), (0, b"ENDSEC"),
                          (0, b"EOF")))
    return b"".join(out)


def _huge_repeat(rng, data, fmt, ci):
    if fmt == "gerber":
        roll = rng.randrange(3)
        if roll == 0:
            nx = rng.choice((10, 1000, 10**6, 10**9, 10**15))
            ny = rng.choice((1, 10, 10**6, 10**12))
            head, end = _after_header(data), _before_end(data)
            closing = b"%SR*%\n" if rng.random() < 0.5 else b""
            out = data[:head] + b"%%SRX%dY%dI1.0J1.0*%%\n" % (nx, ny) + data[head:end] + closing \
                + data[end:]
            return out, f"%SR {nx} x {ny}"
        if roll == 1:
            small = b"%FSLAX24Y24*%%MOIN*%%ADD10C,0.1*%D10*%SRX" + \
                str(rng.choice((10**7, 10**12, 99999999999))).encode() + \
                b"Y" + str(rng.choice((1, 10**7))).encode() + b"I0.1J0.1*%X0Y0D02*X1D01*%SR*%M02*"
            return small, "the 104-byte %SR file"
    if fmt == "drill" and rng.random() < 0.4:
        count = rng.choice((10, 1000, 10**6, 10**9, 10**30))
        at = _drill_body(data)
        step = rng.choice((b"X1000", b"Y-5", b"X0.1Y0.1", b"X" + b"9" * 12))
        return data[:at] + b"X1000Y1000\nR%d%s\n" % (count, step) + data[at:], \
            f"repeat R{count}"
    if fmt == "dxf" and rng.random() < 0.5:
        columns = rng.choice((10, 1000, 32767))
        rows = rng.choice((1, 100, 32767))
        return _dxf_nested_blocks(rng, rng.choice((2, 3, 6)), ci, columns, rows), \
            f"MINSERT {columns} x {rows}, nested"
    # Lines (statements, entities) repeated many times.
    lines = data.split(b"\n")
    if len(lines) < 3:
        return data * rng.randint(2, 1000), "the whole file repeated"
    at = rng.randrange(1, len(lines) - 1)
    span = rng.choice((1, 2, 4, 20)) if fmt != "dxf" else 2 * rng.choice((1, 2, 7))
    at -= at % 2 if fmt == "dxf" else 0
    piece = b"\n".join(lines[at:at + span]) + b"\n"
    if ci:
        times = rng.choice((10, 1000, 20_000))
    else:
        times = rng.choice((10, 1000, 100_000, 1_000_000) if fmt != "dxf" else (10, 1000, 30_000))
        times = min(times, 500_000 // piece.count(b"\n"))  # half a million lines at most
        if fmt == "gcode" and rng.random() < 0.08:
            piece, times = b"G1 X1.5 Y2.25\nG1 X3 Y4\n", 5_000_000  # ten million lines
    prefix = b"\n".join(lines[:at]) + b"\n"
    return prefix + piece * times + b"\n".join(lines[at:]), \
        f"{span} lines at line {at + 1} repeated {times} times"


def _oddity(rng, data, fmt, ci):
    if fmt == "gerber":
        roll = rng.randrange(10)
        head = _after_header(data)
        if roll == 0:
            m = re.search(rb"%ADD\d+[A-Za-z_.$][^,%*]*,[\d.]+", data)
            if m:
                return data[:m.end()] + b"*" + data[m.end():], "stray '*' inside %AD"
            return data[:head] + b"%ADD77C,0.1*0.05*%\n" + data[head:], "stray '*' inside %AD"
        if roll == 1:
            return data[:head] + b"%IFmissing-include.gbr*%\n" + data[head:], "%IF of a missing file"
        if roll == 2:
            end = _before_end(data)
            return data[:end] + b"G36*\nX0Y0D02*\nX100Y0D01*\nX100Y100D01*\n" + data[end:], \
                "region open at M02"
        if roll == 3:
            at = data.find(b"%FS")
            return data[:max(at, 0)] + b"X100Y100D02*\nX200Y200D01*\n" + data[max(at, 0):], \
                "coordinates before %FS"
        if roll == 4:
            return data + b"\x00" * rng.choice((1, 100, 10_000)), "NUL padding at the end"
        if roll == 5:
            return b"\xef\xbb\xbf" + data.replace(b"\n", b"\r\n"), "BOM and CRLF"
        if roll == 6:
            return data[:head] + b"%ADD11C,0.1" + data[head:], "an unclosed %"
        if roll == 7:
            return rng.choice((b"", b"   \n\n", b"%", b"*", b"M02*", b"%FSLAX24Y24*%")), "a tiny file"
        if roll == 8:
            return data.replace(b"*%", b"%", 1), "missing '*' before '%'"
        return data.replace(b"D01", b"D1", 50).replace(b"G01", b"G1", 50) + b"\x1a", \
            "short codes and a Ctrl-Z"
    if fmt == "gcode":
        roll = rng.randrange(7)
        if roll == 0:
            return data + b"(unclosed comment\n", "unclosed comment"
        if roll == 1:
            return data.replace(b"\n", b"\r\n"), "CRLF"
        if roll == 2:
            return b"\xef\xbb\xbf" + data + b"\x00" * 64, "BOM and NUL padding"
        if roll == 3:
            return data.replace(b"1", "\u0661".encode(), 3), "Arabic-Indic digits"
        if roll == 4:
            return data + b"M2\nG1 X1\n", "code after M2"
        if roll == 5:
            return b"G1 X1 Y1 G2 X2 Y2 R1 I1\nG4 P-1\nG1 F0\nT99999999999999\n" + data, "bad words"
        return rng.choice((b"", b"\n", b"%\n", b"G\n", b"N1\n")), "a tiny file"
    if fmt == "drill":
        return _drill_oddity(rng, data)
    roll = rng.randrange(6)
    if roll == 0:
        return re.sub(rb"(\n *-?\d+)\.(\d+\r?\n)", rb"\1,\2", data, count=20), "decimal commas"
    if roll == 1:
        return data.replace(b"EOF", b"", 1), "no EOF"
    if roll == 2:
        at = data.find(b"ENTITIES")
        return (data[:at] + b"ENTITIES\n  0\nENDSEC\n  0\nSECTION\n  2\n" + data[at:]) if at >= 0 \
            else data, "a section twice"
    if roll == 3:
        return data + b"\x1a" * rng.choice((1, 3)), "Ctrl-Z padding"
    if roll == 4:
        return data.replace(b"\n", b"\r\n"), "CRLF"
    return rng.choice((b"", b"0\nSECTION\n", b"AutoCAD Binary DXF\r\n\x1a\x00", b"999\n")), \
        "a tiny file"


def _drill_body(data: bytes) -> int:
    """Where a drill file's body starts (after the header's '%'), else its end."""
    at = data.find(b"\n%")
    if at < 0:
        return len(data)
    end = data.find(b"\n", at + 1)
    return len(data) if end < 0 else end + 1


_DRILL_ODDITIES = (
    (b"G00X0Y0\nM15\nG02X10Y0A1\nM16\n", "an arc radius shorter than half its chord"),
    (b"G00X0Y0\nM15\nG03X0Y0I5J0\nG02X0Y0\nM16\n", "a full circle and an arc without centre"),
    (b"T0\nX1Y1\n", "a hole after T0"),
    (b"T987654321\nX1Y1\n", "an undefined tool"),
    (b"G91\n" + b"X9999999Y9999999\n" * 50, "incremental steps out to the far distance"),
    (b"G93X999999999999Y1\nX1Y1\n", "a zero set far away"),
    (b"METRIC,LZ,00000000.00000000\nX12345678901234567Y1\n", "a format of 16 digits"),
    (b"M47,operator text\nM97,canned\nM71\nM72\nICI,ON\nX1\nICI,OFF\n", "text and modes"),
    (b"X1Y1G85\nG85X2Y2\nG85\n", "G85 with a side missing"),
    (b"T1C-1\nT2C\nT3C1e5\nTC1\n", "bad tool sizes"),
)


def _drill_oddity(rng, data):
    roll = rng.randrange(len(_DRILL_ODDITIES) + 4)
    if roll < len(_DRILL_ODDITIES):
        insert, how = _DRILL_ODDITIES[roll]
        at = _drill_body(data)
        return data[:at] + insert + data[at:], how
    roll -= len(_DRILL_ODDITIES)
    if roll == 0:
        return b"\xef\xbb\xbf" + data.replace(b"\n", b"\r\n"), "BOM and CRLF"
    if roll == 1:
        return data[_drill_body(data):], "no header"
    if roll == 2:
        return data.replace(b"M30", b"", 1) + b"\x00" * 64, "no M30, NUL padding"
    return rng.choice((b"", b"M48\n", b"%\n", b"M48\n%\nX1Y1\n", b"T1C1\nX\n")), "a tiny file"


def _binary(rng, data, fmt, ci):
    roll = rng.randrange(4)
    chunk = bytes(rng.randrange(256) for _ in range(rng.choice((1, 4, 64, 1024))))
    if roll == 0 and data:
        at = rng.randrange(len(data))
        return data[:at] + chunk + data[at:], f"{len(chunk)} random bytes at {at}"
    if roll == 1:
        return data + chunk, f"{len(chunk)} random bytes appended"
    if roll == 2:
        return chunk * rng.choice((1, 16)), "random bytes only"
    return data[:16] + b"\x00" + data[16:], "a NUL at byte 16"


_MUTATORS = {"flip": _flip, "truncate": _truncate, "splice": _splice, "huge-number": _huge_number,
             "deep-nesting": _deep_nesting, "huge-repeat": _huge_repeat, "oddity": _oddity,
             "binary": _binary}
