"""The interactive console (`galileo-cnc` with no arguments): see docs/console.md."""

from __future__ import annotations

from pathlib import Path

from prompt_toolkit.application import create_app_session
from prompt_toolkit.input import Input
from prompt_toolkit.output import Output

from galileo_cnc.config import userdirs
from galileo_cnc.config.machine import MachineConfig


def run_console(port: str | None, baud: int, config: MachineConfig, *,
                history_path: Path | None = None, input: Input | None = None,
                output: Output | None = None, config_path: Path | None = None) -> int:
    """Run the console until `exit` or Ctrl-D; the exit code (0). `config_path`
    is the profile behind `config`, simulated by `sim://`."""
    from galileo_cnc.console.app import Console

    with create_app_session(input=input, output=output):
        console = Console(port, baud, config, history_path or userdirs.history_path(),
                          config_path)
        return console.run()


__all__ = ["run_console"]
