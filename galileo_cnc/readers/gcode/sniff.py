"""Is this text G-code? Content sniffing for files whose extension says little.

G-code lines are words (a letter and a number). Gerber is told apart by its `%`
parameter blocks and the `*` that ends every statement; Excellon drill and NC
route files by their M48 header, M71/M72 unit and M15/M16 tool codes, words such
as INCH or T01C0.8, and coordinates with an implied decimal point (X00130500),
which G-code would read as a hundred metres.
"""

from __future__ import annotations

import re

from galileo_cnc.readers.gcode.codes import PARAMETER_LETTERS
from galileo_cnc.readers.gcode.lexer import has_code, strip_comments

_WORD = r"[A-Za-z]\s*[-+]?(?:\d+\.?\d*|\.\d+)"
_CODE_LINE = re.compile(rf"\s*(?:{_WORD}\s*)+(?:\*\s*\d+\s*)?", re.ASCII)
_WORDS = re.compile(r"([A-Za-z])\s*([-+]?(?:\d+\.?\d*|\.\d+))", re.ASCII)

_LETTERS = PARAMETER_LETTERS | {"G", "M", "N"}
_EXCELLON_M_CODES = {"15", "16", "48", "71", "72"}  # Z down/up, header, metric, inch
_COORDINATE_LETTERS = set("XYIJ")
SNIFF_CHARS = 65_536  # look no further than this into the text
SNIFF_CODE_LINES = 8  # lines of code that must all look right


def looks_like_gcode(text: str) -> bool:
    """True if the first lines of code (comments, blanks and '%' skipped) are G-code words."""
    head = text[:SNIFF_CHARS]
    lines = head.splitlines()
    if len(text) > SNIFF_CHARS and lines:
        lines.pop()  # may be cut in the middle
    code_lines = 0
    for raw in lines:
        line = raw.strip().removeprefix("\ufeff")
        if not line or line == "%":
            continue
        if line.startswith("%"):
            return False  # a Gerber parameter block
        if not has_code(line):
            continue
        code = strip_comments(line)
        if code.endswith("*"):
            return False  # a Gerber statement end
        verdict = _classify_code_line(code)
        if verdict == "excellon":
            return False
        if verdict == "other":
            # A bad line after good ones is G-code with a mistake: let the reader
            # name the line, rather than calling the whole file unknown.
            return code_lines > 0
        code_lines += 1
        if code_lines >= SNIFF_CODE_LINES:
            break
    return code_lines > 0


def _classify_code_line(code: str) -> str:
    """'gcode', 'excellon' (drill/route file) or 'other'."""
    if _CODE_LINE.fullmatch(code) is None:
        return "other"
    for letter, number in _WORDS.findall(code):
        letter = letter.upper()
        if letter not in _LETTERS:
            return "other"
        if letter == "M" and number.lstrip("0") in _EXCELLON_M_CODES:
            return "excellon"
        if letter in _COORDINATE_LETTERS and _implied_decimal(number):
            return "excellon"
    return "gcode"


def _implied_decimal(number: str) -> bool:
    """X00130500 or X130500: an Excellon-style integer coordinate, not millimetres."""
    digits = number.lstrip("+-")
    if "." in digits:
        return False
    return len(digits) >= 5 or (len(digits) >= 3 and digits[0] == "0")
