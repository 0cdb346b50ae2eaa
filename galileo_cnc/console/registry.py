"""One registry of console commands: it feeds dispatch, completion and `help`."""

from __future__ import annotations

import difflib
from dataclasses import dataclass
from typing import Any, Callable

from prompt_toolkit.completion import Completer, NestedCompleter


@dataclass(frozen=True, slots=True)
class ConsoleCommand:
    name: str
    usage: str                          # e.g. "getg [FILE]"
    summary: str                        # one line, used when helpfile.f has no section
    run: Callable[[Any, list[str]], None]       # (the console.app.Console, its arguments)
    needs_machine: bool = False
    #: completion of the arguments (None: none); a callable gets the registry's names
    arguments: Completer | Callable[[list[str]], Completer] | None = None
    #: the command gets the rest of the line as typed, as one argument (`send $J=X1 F60`)
    raw_arguments: bool = False


class Registry:
    def __init__(self, commands: list[ConsoleCommand]):
        self._commands = {command.name: command for command in commands}

    def __iter__(self):
        return iter(self._commands.values())

    @property
    def names(self) -> list[str]:
        return list(self._commands)

    def get(self, name: str) -> ConsoleCommand | None:
        return self._commands.get(name.lower())

    def closest(self, word: str) -> str | None:
        """The command name a mistyped word most likely meant, if any is close."""
        matches = difflib.get_close_matches(word.lower(), self.names, n=1, cutoff=0.5)
        return matches[0] if matches else None

    def completer(self) -> Completer:
        nested: dict[str, Completer | None] = {}
        for command in self:
            arguments = command.arguments
            if callable(arguments) and not isinstance(arguments, Completer):
                arguments = arguments(self.names)
            nested[command.name] = arguments
        return NestedCompleter(nested, ignore_case=True)
