"""`galileo-cnc` and `python -m galileo_cnc`: the shell's commands (cli/), or with no
command the interactive console (console/). The one module above both front ends,
so neither imports the other."""

from __future__ import annotations

from galileo_cnc.cli.main import main as run_command


def start_console(profile) -> int:
    from galileo_cnc.console import run_console      # prompt_toolkit: only for the console

    return run_console(profile.port, profile.baud, profile.config, config_path=profile.path)


def main(argv: list[str] | None = None) -> int:
    return run_command(argv, start_console=start_console)


if __name__ == "__main__":
    raise SystemExit(main())
