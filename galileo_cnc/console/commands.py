"""The console's commands, in the order `help` lists them."""

from __future__ import annotations

from prompt_toolkit.completion import PathCompleter, WordCompleter

from galileo_cnc.console import getg, machine_commands, preview, resume, setup, show_help
from galileo_cnc.console.registry import ConsoleCommand, Registry


def _leave(console, arguments: list[str]) -> None:
    console.leaving = True


def _send(console, arguments: list[str]) -> None:
    line = arguments[0] if arguments else console.ask("line for the machine: ")
    if line:
        console.machine.send_line(line, console.say)


def _home(console, arguments: list[str]) -> None:
    machine_commands.home(console, arguments)
    console.say(console.machine.origin_after_home())      # the user's origin may be gone


def build_registry() -> Registry:
    return Registry([
        ConsoleCommand("help", "help [COMMAND]", "print the help, or one command's",
                       show_help.run, arguments=lambda names: WordCompleter(names)),
        ConsoleCommand("getg", "getg [FILE]", "plot a Gerber, G-code or DXF file",
                       getg.run, needs_machine=True,
                       arguments=PathCompleter(expanduser=True)),
        ConsoleCommand("preview", "preview [FILE] [-o OUT]",
                       "write a picture of what getg would plot (each side of a board)",
                       preview.run, arguments=PathCompleter(expanduser=True)),
        ConsoleCommand("setup", "setup", "jog the head with the keypad, set the feed rate",
                       setup.run, needs_machine=True),
        ConsoleCommand("status", "status", "the machine's state and position",
                       machine_commands.status, needs_machine=True),
        ConsoleCommand("ports", "ports", "list the serial ports", machine_commands.ports),
        ConsoleCommand("connect", "connect [PORT]", "reconnect, to PORT if given",
                       machine_commands.connect),
        ConsoleCommand("home", "home", "drive the axes to their end-stops",
                       _home, needs_machine=True),
        ConsoleCommand("unlock", "unlock", "leave the alarm state (after a homing error)",
                       machine_commands.unlock, needs_machine=True),
        ConsoleCommand("send", "send LINE", "send a line to the machine ($22=1, G0 X10)",
                       _send, needs_machine=True, raw_arguments=True),
        ConsoleCommand("resume", "resume", "continue an interrupted job",
                       resume.run, needs_machine=True),
        ConsoleCommand("exit", "exit", "leave the console", _leave),
    ])
