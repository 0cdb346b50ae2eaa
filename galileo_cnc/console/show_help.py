"""`help [COMMAND]`: the text of helpfile.f, the user's edited copy first."""

from __future__ import annotations

from galileo_cnc.config.userdirs import user_helpfile_path
from galileo_cnc.console.helptext import load_help


def run(console, arguments: list[str]) -> None:
    text = load_help(user_helpfile_path())
    if not arguments:
        console.say(text.full())
        _mention_undocumented(console, text.sections)
        return
    topic = arguments[0].lower()
    section = text.sections.get(topic)
    if section is not None:
        console.say(section)
        return
    command = console.registry.get(topic)
    if command is not None:       # the help file (maybe an old edited copy) lacks it
        console.say(f"{command.usage}\n    {command.summary}")
        return
    console.say(f"no help for {topic!r}; commands: {', '.join(console.registry.names)}")


def _mention_undocumented(console, sections: dict[str, str]) -> None:
    for command in console.registry:
        if command.name not in sections:
            console.say(f"{command.usage}\n    {command.summary}")
