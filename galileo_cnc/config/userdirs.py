"""Where galileo-cnc keeps the user's files: history and the job journal (data),
the machine profile and an edited help file (config).

`GALILEO_CNC_HOME` puts everything in one directory (tests, portable installs);
otherwise the XDG base directories on Unix and %APPDATA% on Windows.
"""

from __future__ import annotations

import os
from pathlib import Path

HOME_ENV = "GALILEO_CNC_HOME"
APP_DIR_NAME = "galileo-cnc"


def _base(xdg_env: str, unix_default: str) -> Path:
    home = os.environ.get(HOME_ENV)
    if home:
        return Path(home)
    xdg = os.environ.get(xdg_env)
    if xdg:
        return Path(xdg) / APP_DIR_NAME
    if os.name == "nt" and os.environ.get("APPDATA"):
        return Path(os.environ["APPDATA"]) / APP_DIR_NAME
    return Path.home() / unix_default / APP_DIR_NAME


def data_dir() -> Path:
    """History and other files the program writes for itself."""
    return _base("XDG_DATA_HOME", ".local/share")


def config_dir() -> Path:
    """Files the user edits: a copy of helpfile.f here wins over the shipped one."""
    return _base("XDG_CONFIG_HOME", ".config")


def history_path() -> Path:
    return data_dir() / "history"


def user_helpfile_path() -> Path:
    return config_dir() / "helpfile.f"
