"""Splitting one G-code line into words, and exact decimal numbers.

A line is words (a letter and a number, spaces allowed between and around them),
comments in ( ) or after ;, and an optional RepRap-style checksum `*NN` at the end.
Numbers are decimal text; they are turned into integers with integer arithmetic
only, never through float, so 0.1 mm is exactly 100 000 nm.
"""

from __future__ import annotations

import re
from functools import lru_cache, reduce
from operator import xor

from galileo_cnc.errors import GcodeError, SourcePos
from galileo_cnc.program.ops import NM_PER_MM

# One token: a word (number optional, so its absence can be reported), or any
# other non-blank character, which is then an error. re.ASCII keeps \d and \s to
# ASCII, so Unicode digits or spaces are reported instead of silently accepted.
_TOKEN = re.compile(r"([A-Za-z])\s*([-+]?(?:\d+\.?\d*|\.\d+))?|(\S)", re.ASCII)
_COMMENT = re.compile(r"\([^)]*\)|;.*")
_CHECKSUM = re.compile(r"\*\s*(\d*)\s*$", re.ASCII)

# Longer numbers are refused rather than rounded: no CAM writes them, and the
# bounds keep int() off huge strings and every result far inside int64.
MAX_INTEGER_DIGITS = 12
MAX_FRACTION_DIGITS = 30

_POW10 = [10**n for n in range(MAX_FRACTION_DIGITS + 1)]

# A word: (upper-case letter, number text, 1-based column). Plain tuples, as a
# big file has millions of them.
Word = tuple[str, str, int]


def error(source: str, line: int, col: int, message: str, text: str = "") -> GcodeError:
    return GcodeError(SourcePos(source, line, col), message, text)


def split_words(raw: str, source: str, line: int) -> list[Word]:
    """The words of one line, comments and checksum removed and verified."""
    code = raw
    if "(" in code or ")" in code:
        code = _blank_comments(raw, source, line)
    else:
        semicolon = code.find(";")
        if semicolon >= 0:
            code = code[:semicolon]
    if "*" in code:
        code = _check_checksum(raw, code, source, line)
    words = []
    for m in _TOKEN.finditer(code):
        letter, number, junk = m.groups()
        if number is None:
            col = m.start() + 1
            if junk is not None:
                raise error(source, line, col, f"unexpected character {junk!r}: expected a "
                            "word such as G1 or X10", raw)
            raise error(source, line, col, f"expected a number after '{letter}'", raw)
        words.append((letter.upper(), number, m.start() + 1))
    return words


def _blank_comments(raw: str, source: str, line: int) -> str:
    # Comments become spaces so the columns of the words after them stay right.
    code = _COMMENT.sub(lambda m: " " * len(m.group()), raw)
    for char, what in (("(", "a ')' to close the comment"), (")", "a '(' before ')'")):
        at = code.find(char)
        if at >= 0:
            raise error(source, line, at + 1, f"expected {what}", raw)
    return code


def _check_checksum(raw: str, code: str, source: str, line: int) -> str:
    """Verify `*NN` (XOR of the bytes before '*', as RepRap firmware computes it)."""
    star = code.find("*")
    m = _CHECKSUM.match(code, star)
    if m is None or not m.group(1):
        raise error(source, line, star + 1,
                    "expected a checksum: '*' followed by digits at the end of the line", raw)
    start = len(raw) - len(raw.lstrip())
    computed = reduce(xor, raw[start:star].encode("utf-8", "replace"), 0)
    stated = m.group(1)
    if len(stated) > 3 or int(stated) != computed:
        raise error(source, line, star + 1,
                    f"checksum mismatch: the line's bytes give {computed}, "
                    f"the line says {stated[:12]}", raw)
    return code[:star]


def scaled(text: str, scale: int, divisor: int = 1) -> int | None:
    """The decimal `text` times scale / divisor, rounded half away from zero.

    None if the number has more digits than MAX_INTEGER_DIGITS or
    MAX_FRACTION_DIGITS (the caller reports it).
    """
    whole, _, fraction = text.partition(".")
    if divisor == 1 and scale == NM_PER_MM and len(fraction) <= 6 and len(whole) <= 8:
        return int(whole + fraction.ljust(6, "0"))  # the common case: exact, no rounding
    negative = whole.startswith("-")
    digits = whole.lstrip("+-").lstrip("0")
    if len(digits) > MAX_INTEGER_DIGITS or len(fraction) > MAX_FRACTION_DIGITS:
        return None
    denominator = _POW10[len(fraction)] * divisor
    quotient, remainder = divmod(int(digits + fraction or "0") * scale, denominator)
    if 2 * remainder >= denominator:
        quotient += 1
    return -quotient if negative else quotient


@lru_cache(maxsize=512)
def code_number(text: str) -> str | None:
    """Canonical text of a G or M code number: '01' -> '1', '92.10' -> '92.1'.

    None for signed numbers, which are never valid codes.
    """
    if text[0] in "+-":
        return None
    whole, _, fraction = text.partition(".")
    whole = whole.lstrip("0") or "0"
    fraction = fraction.rstrip("0")
    return f"{whole}.{fraction}" if fraction else whole


def strip_comments(text: str) -> str:
    """`text` without its comments (unclosed ones stay, for the caller to refuse)."""
    return _COMMENT.sub(" ", text).strip()


def has_code(text: str) -> bool:
    """True if `text` holds anything besides comments and blanks."""
    return bool(_COMMENT.sub("", text).strip())


def whole_number(text: str) -> int | None:
    """A non-negative integer written without a fraction (N, T), else None."""
    if not text.isdigit() or len(text.lstrip("0")) > MAX_INTEGER_DIGITS:
        return None
    return int(text)
