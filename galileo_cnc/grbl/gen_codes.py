"""Writes codes.py from GRBL's own tables (doc/csv of the GRBL 1.1h source tree).

    python3 -m galileo_cnc.grbl.gen_codes third_party/grbl-1.1h/doc/csv

The GRBL tree is not shipped to users, so its texts live in the package as a
generated module; tests/grbl/test_codes.py checks it still matches the csv.
"""

from __future__ import annotations

import csv
import sys
from pathlib import Path

TABLES = (
    # (csv file, Python name, what the table is)
    ("error_codes_en_US.csv", "ERRORS", "error:N -> (message, description)"),
    ("alarm_codes_en_US.csv", "ALARMS", "ALARM:N -> (message, description)"),
    ("setting_codes_en_US.csv", "SETTINGS", "$N -> (setting, units, description)"),
)


def read_table(path: Path) -> dict[int, tuple[str, ...]]:
    with open(path, newline="", encoding="utf-8") as f:
        rows = list(csv.reader(f))
    table = {}
    for number, row in enumerate(rows[1:], start=2):
        if not row:
            continue
        try:
            table[int(row[0])] = tuple(cell.strip() for cell in row[1:])
        except ValueError:
            raise ValueError(f"{path}:{number}: expected a code number, got {row[0]!r}") from None
    return table


def render(csv_dir: Path) -> str:
    out = ['"""GRBL 1.1h\'s error, alarm and setting texts, generated from its doc/csv.',
           "",
           "Do not edit: run `python3 -m galileo_cnc.grbl.gen_codes <grbl>/doc/csv`.",
           '"""', "", "# fmt: off"]
    for filename, name, what in TABLES:
        out.append("")
        out.append(f"#: {what}   ({filename})")
        out.append(f"{name}: dict[int, tuple[str, ...]] = {{")
        for code, cells in sorted(read_table(csv_dir / filename).items()):
            out.append(f"    {code}: {cells!r},")
        out.append("}")
    return "\n".join(out) + "\n"


def main(argv: list[str]) -> int:
    if len(argv) != 1:
        print(__doc__.strip().splitlines()[2].strip(), file=sys.stderr)
        return 1
    target = Path(__file__).with_name("codes.py")
    target.write_text(render(Path(argv[0])), encoding="utf-8")
    print(f"wrote {target}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main(sys.argv[1:]))
