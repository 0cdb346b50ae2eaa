"""Limits that keep hostile or broken input from costing unbounded time or memory.

Each is far beyond what a real file needs (docs/reliability.md gives the reasons and
the corpus figures). The four that a genuine, very large drawing can reach are
read from the environment when a file is read, so a user can raise them without code:

    GALILEO_MAX_OPS=20000000 galileo-cnc info huge.nc
    GALILEO_MAX_FILE_MB=2048 galileo-cnc info huge.gbr
    GALILEO_MAX_BLOCK_ENTITIES=2000000 galileo-cnc info city-map.dxf
    GALILEO_MAX_APERTURES=100000 galileo-cnc info every-pad-its-own-aperture.gbr

`read_file` and the readers also take `max_ops=` (None: the environment, else
MAX_OPS). The others are constants of the formats' sanity and are raised by editing
them here.
"""

from __future__ import annotations

import os

# Operations one file may produce (rows of the op table, 72 bytes each: 72 MB; about
# five seconds of reading G-code, hours of plotting; the Gerber corpus needs at most
# 120,000).
# The readers check it as they go, so %SR / %AB / MINSERT expansion and huge files
# are refused early, at the statement that crossed it.
MAX_OPS = 1_000_000
MAX_OPS_ENV = "GALILEO_MAX_OPS"

# DXF: entities drawn through block references (INSERT, MINSERT cells, nested), each
# copy counted. Expansion costs about 40 us an entity in ezdxf, so this is ten
# seconds; the corpus needs at most 10,000. Checked before a block is expanded.
MAX_BLOCK_ENTITIES = 250_000
MAX_BLOCK_ENTITIES_ENV = "GALILEO_MAX_BLOCK_ENTITIES"

# Gerber: aperture and macro definitions (%AD, %AM statements) in one file. Each costs
# up to a tenth of a millisecond (a macro is evaluated per %AD); the corpus has at
# most 756.
MAX_APERTURES = 20_000
MAX_APERTURES_ENV = "GALILEO_MAX_APERTURES"

# Bytes of one file. Reading keeps the bytes and the text: about three times this.
MAX_FILE_MB = 256
MAX_FILE_MB_ENV = "GALILEO_MAX_FILE_MB"

# Gerber coordinates (after %FS scaling, incremental sums, %SR steps and the image
# transforms) further than this from the origin are refused: 10 m, far beyond any
# board or plotter, and it keeps every sum and product of the vectorised path inside
# int64 (no silent wrap-around).
MAX_GERBER_COORD_NM = 10**10

# Gerber decimal numbers (aperture and macro parameters, %SR steps, %LS, %SF ...):
# characters of one number. The corpus's longest is 20.
MAX_NUMBER_CHARS = 64

# Gerber macro arithmetic: nesting of parentheses and unary signs in one expression,
# and the size of any intermediate value (bits of its numerator or denominator), so a
# macro that squares a value again and again stops at once.
MAX_EXPRESSION_DEPTH = 64
MAX_MACRO_VALUE_BITS = 256

# Gerber rotations (polygon apertures, macro primitives, %LR) in degrees either way,
# and scale factors (%LS, %SF): beyond them float trigonometry and int64 both fail.
MAX_ROTATION_DEGREES = 3600
MAX_SCALE = 1000

# Gerber include files (%IF) within include files.
MAX_INCLUDE_DEPTH = 8


def _from_env(name: str, default: int) -> int:
    text = os.environ.get(name, "").strip().replace("_", "")
    if not text:
        return default
    try:
        value = int(text)
    except ValueError:
        return default
    return value if value > 0 else default


def max_ops(explicit: int | None = None) -> int:
    """The op limit in force: `explicit`, else $GALILEO_MAX_OPS, else MAX_OPS."""
    if explicit is not None:
        return explicit
    return _from_env(MAX_OPS_ENV, MAX_OPS)


def max_block_entities() -> int:
    return _from_env(MAX_BLOCK_ENTITIES_ENV, MAX_BLOCK_ENTITIES)


def max_apertures() -> int:
    return _from_env(MAX_APERTURES_ENV, MAX_APERTURES)


def max_file_bytes() -> int:
    return _from_env(MAX_FILE_MB_ENV, MAX_FILE_MB) * 1024 * 1024


def ops_message(limit: int, what: str, unit: str = "operations",
                how: str = f"set {MAX_OPS_ENV}=<count> or pass max_ops=") -> str:
    """The text of an op-limit error: what crossed it, the limit and how to raise it.
    `what` ends in a verb: 'the file makes', '%SR ... would make'."""
    return f"{what} more than {limit:,} {unit}, the limit ({how} to raise it)"
