"""The console's help text: helpfiles/helpfile.f, split into one section per command.

Format of helpfile.f (plain text, meant to be edited by hand):

- text before the first section is the overview that `help` prints first;
- a line holding only `[name]` starts the section for the command `name`;
  everything up to the next such line belongs to it (the header line itself is
  not printed).

A copy of the file in the user's config directory wins over the shipped one, so
the help can be edited after installation.
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field
from importlib import resources
from pathlib import Path

HELPFILE_NAME = "helpfile.f"
_SECTION_RE = re.compile(r"^\[([A-Za-z][\w-]*)\]\s*$")
#: helpfiles/ at the top of a source checkout (installed, it is galileo_cnc.helpfiles).
_CHECKOUT_HELPFILES = Path(__file__).resolve().parents[2] / "helpfiles"


@dataclass(slots=True)
class HelpText:
    overview: str
    sections: dict[str, str] = field(default_factory=dict)   # command name -> text
    source: str = ""

    def full(self) -> str:
        parts = [self.overview] if self.overview else []
        parts.extend(self.sections.values())
        return "\n\n".join(parts)


def parse_help(text: str, source: str = "") -> HelpText:
    overview: list[str] = []
    sections: dict[str, list[str]] = {}
    current = overview
    for line in text.splitlines():
        header = _SECTION_RE.match(line)
        if header:
            current = sections.setdefault(header.group(1).lower(), [])
        else:
            current.append(line.rstrip())
    return HelpText("\n".join(overview).strip("\n"),
                    {name: "\n".join(lines).strip("\n") for name, lines in sections.items()},
                    source)


def shipped_help_text() -> str:
    try:
        return (resources.files("galileo_cnc.helpfiles") / HELPFILE_NAME).read_text("utf-8")
    except ModuleNotFoundError:  # running from a checkout that is not installed
        return (_CHECKOUT_HELPFILES / HELPFILE_NAME).read_text("utf-8")


def load_help(user_copy: Path | None = None) -> HelpText:
    """The user's edited copy if there is one, else the shipped help file."""
    if user_copy is not None and user_copy.is_file():
        return parse_help(user_copy.read_text("utf-8", errors="replace"), str(user_copy))
    return parse_help(shipped_help_text(), HELPFILE_NAME)
