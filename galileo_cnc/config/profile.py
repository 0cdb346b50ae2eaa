"""The machine profile: one TOML file with the machine and how to reach it.

```toml
[machine]            # any MachineConfig field (galileo_cnc/config.py); the seed's machine by default
steps_per_rev = 200
pitch_mm = 1.25
junction_deviation_mm = 0.01     # speed through corners (docs/motion.md §5.7); 0: stop at each
vertex_speed_change_mm_s = 2.0   # the largest per-axis speed change at a vertex

[mill]               # a mill's tool and cut (galileo_cnc/config/mill.py, docs/mill.md)
tool = "vbit"

[serial]
port = "/dev/ttyACM0"   # COMx, /dev/tty..., a pty path or a pyserial URL; absent: auto-detect
baud = 115200
```

Found at `--profile FILE`, else `$GALILEO_CNC_HOME/profile.toml` or
`$XDG_CONFIG_HOME/galileo-cnc/profile.toml` (~/.config/galileo-cnc) if it exists,
else the defaults. Command-line `--port`/`--baud` win over the file.
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path

from galileo_cnc.config.hardware import BAUD_RATES, DEFAULT_BAUD
from galileo_cnc.config.machine import ConfigError, MachineConfig, read_toml, unknown_key_text
from galileo_cnc.config.mill import MillConfig
from galileo_cnc.config.userdirs import config_dir

PROFILE_NAME = "profile.toml"
#: the profile's tables: the machine, its pens, a GRBL board's pen, a mill's tool, how to
#: reach it
TABLES = ("machine", "pens", "grbl", "mill", "serial")
TABLE_NAMES = tuple(f"[{name}]" for name in TABLES)


@dataclass(frozen=True)
class Profile:
    config: MachineConfig
    port: str | None = None
    baud: int = DEFAULT_BAUD
    path: Path | None = None
    mill: MillConfig = MillConfig()      # the [mill] table, else a 30 deg V-bit's defaults


def load_profile(path: str | os.PathLike | None = None, *, port: str | None = None,
                 baud: int | None = None) -> Profile:
    """The profile at `path` (or the user's, or the defaults), with `port`/`baud` applied."""
    found = Path(path) if path is not None else config_dir() / PROFILE_NAME
    if path is None and not found.exists():
        found = None
    data = read_toml(found, "the profile") if found is not None else {}
    tables = sorted(key for key, value in data.items() if isinstance(value, dict))
    unknown = [name for name in tables if name not in TABLES]
    if unknown:        # a misspelt table would be read as nothing
        named = ", ".join(unknown_key_text(f"[{name}]", TABLE_NAMES) for name in unknown)
        raise ConfigError(f"{found}: unknown table(s): {named} "
                          f"(known: {', '.join(TABLE_NAMES)})")
    serial_table = data.get("serial", {})
    unknown = sorted(set(serial_table) - {"port", "baud"})
    if unknown:
        raise ConfigError(f"{found}: [serial] has unknown key(s): "
                          f"{', '.join(unknown_key_text(k, ('port', 'baud')) for k in unknown)} "
                          f"(known: port, baud)")
    config = MachineConfig.from_mapping(data, str(found)) if data else MachineConfig()
    if baud is not None:
        where = "--baud"
    else:
        baud, where = serial_table.get("baud", DEFAULT_BAUD), f"{found}: [serial] baud"
    if isinstance(baud, bool) or baud not in BAUD_RATES:
        raise ConfigError(f"{where}: baud rate {baud!r} not supported (use one of "
                          f"{', '.join(map(str, BAUD_RATES))})")
    profile_port = serial_table.get("port")
    if profile_port is not None and not isinstance(profile_port, str):
        raise ConfigError(f"{found}: [serial] port must be text (a name, path or URL), "
                          f"got {profile_port!r}")
    mill = MillConfig.from_table(data["mill"], str(found)) if "mill" in data else MillConfig()
    return Profile(config, port or profile_port or None, baud, found, mill)
