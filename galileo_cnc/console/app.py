"""The console: banner, connection line, the `>>` prompt loop and its bottom toolbar.

Commands live in their own modules and reach the console through the registry
(registry.py); this module owns what they share: the machine (a backends.Machine:
our firmware or GRBL, opened by backends.open_machine), the machine configuration,
printing (also from the link's reader thread) and questions.
"""

from __future__ import annotations

import contextvars
import shlex
import threading
import time
from pathlib import Path

from prompt_toolkit import PromptSession
from prompt_toolkit.history import FileHistory, History, InMemoryHistory
from prompt_toolkit.shortcuts import print_formatted_text, prompt

from galileo_cnc import __version__
from galileo_cnc.config.machine import MachineConfig
from galileo_cnc.backends import Machine, MachineView, open_machine
from galileo_cnc.backends.command_line import is_machine_line
from galileo_cnc.config.profile import Profile
from galileo_cnc.console.commands import build_registry
from galileo_cnc.console.plans import PlanCache
from galileo_cnc.errors import GalileoError
from galileo_cnc.transport.link import LinkError, MachineAlarm, PortGone

PROMPT = ">> "
#: the command a line for the machine goes to (`$22=1`, `G0 X10`: backends/command_line.py)
SEND = "send"
#: While the prompt waits, the toolbar's state and position are refreshed this often.
TOOLBAR_REFRESH_S = 0.5


class Console:
    def __init__(self, port: str | None, baud: int, config: MachineConfig,
                 history_path: Path | None, config_path: Path | None = None):
        self.requested_port = port
        self.config_path = config_path
        self.baud = baud
        self.config = config                    # feed changes from `setup` land here
        self.profile = config                   # as read: what the board must be built for
        self.machine: Machine | None = None
        self.last_status: MachineView | None = None
        self.leaving = False
        self.plans = PlanCache()                # getg again, resume: the last plan kept
        self.registry = build_registry()
        self.session: PromptSession = PromptSession(
            history=_open_history(history_path), completer=self.registry.completer(),
            complete_while_typing=False, bottom_toolbar=self.toolbar,
            refresh_interval=TOOLBAR_REFRESH_S)
        self._at_prompt = threading.Event()
        # The app session (terminal) this console runs in, for printing from other threads.
        self._context = contextvars.copy_context()

    # ---- output and questions ----------------------------------------------------
    def say(self, text: str = "") -> None:
        """Print a line; above the prompt or progress bar when one is showing."""
        print_formatted_text(text)

    def say_stage(self, text: str) -> None:
        """What the planning of a large file is at (plan_file's on_stage): seconds a
        stage on the largest layers."""
        self.say(f"{text} ...")

    def say_from_thread(self, text: str) -> None:
        """`say` for the link's reader thread, which does not know our terminal."""
        self._context.copy().run(self.say, text)

    def ask(self, question: str, default: str = "", completer=None) -> str:
        """One line of input; Ctrl-C/Ctrl-D cancel the command (KeyboardInterrupt/EOFError)."""
        return prompt(question, default=default, completer=completer).strip()

    def confirm(self, question: str, default: bool = True) -> bool:
        choices = "[Y/n]" if default else "[y/N]"
        while True:
            answer = self.ask(f"{question} {choices} ").lower()
            if not answer:
                return default
            if answer in ("y", "yes"):
                return True
            if answer in ("n", "no"):
                return False
            self.say("please answer y or n")

    # ---- the machine ----------------------------------------------------------------
    @property
    def link(self):
        """The machine's link (MachineLink or GrblLink), None when not connected."""
        return self.machine.link if self.machine is not None else None

    def connect(self, port: str | None) -> bool:
        """Open `port` (None: find a board, else sim://); a working connection is kept
        when the new one cannot be made, and given up only to reopen the same port."""
        old = self.machine
        if old is not None and (port is None or port == old.port_name):
            self.disconnect()                   # a port opens once: close it first
            old = None
        try:
            machine = open_machine(port, Profile(self.profile, port, self.baud,
                                                 self.config_path),
                                   config=self.config, on_message=self.say_from_thread)
        except GalileoError as error:
            if old is not None:
                self.say(f"{error}; still connected to {old.port_name}")
            else:
                self.say(f"not connected: {error}")
                self.say("type `connect PORT` to try again (`ports` lists them)")
            return False
        if old is not None:
            self.disconnect()
        self.machine = machine
        line = machine.describe()
        if port is None and machine.simulated:
            line += " (no board found)"
        self.say(line)
        with machine.session():
            try:  # the machine starts with its own default feed; make it ours
                machine.set_feed(self.config, self.config.feed_mm_s)
            except LinkError as error:
                self.say(f"could not set the feed rate: {error}")
        self.refresh_status()
        return True

    def jog_with_keypad(self, units: int) -> None:
        """`setup`'s keypad: one jog a key; on a machine that queues jogs, a held key is
        followed and cancelled when let go."""
        if self.machine.queues_jogs:
            from galileo_cnc.console.grbl_keypad import jog_with_keypad
            jog_with_keypad(self, self.machine, units)
        else:
            from galileo_cnc.console.keypad import jog_with_keypad
            jog_with_keypad(self, units)

    def use_config(self, config: MachineConfig) -> None:
        """Plan with `config` from now on; the link's copy goes into the job journal."""
        self.config = config
        if self.machine is not None:
            self.machine.use_config(config)

    def disconnect(self) -> None:
        if self.machine is not None:
            self.machine.close()
            self.machine = None
            self.last_status = None

    def refresh_status(self) -> MachineView | None:
        self.last_status = None
        if self.machine is not None:
            try:
                self.last_status = self.machine.view(timeout_s=1.0)
            except GalileoError:
                pass
        return self.last_status

    def stop_if_moving(self) -> None:
        """After an interrupted command: never leave the head moving."""
        view = self.refresh_status()
        if self.machine is not None:
            self.machine.stop_if_moving(view, self.say)

    def toolbar(self) -> str:
        if self.machine is None:
            return " not connected | type connect [PORT]"
        view = self.last_status
        state = view.state if view else "no answer"
        where = view.where if view else "position unknown"
        return (f" {self.machine.port_name} | {state} | {where} | "
                f"feed {self.config.feed_mm_s:g} mm/s")

    # ---- the loop ------------------------------------------------------------------------
    def banner(self) -> None:
        self.say(f"galileo-cnc {__version__}: console for a home-built CNC pen plotter")
        self.say("type help for the commands, help COMMAND for one of them, exit to leave")

    def run(self) -> int:
        self.banner()
        self.connect(self.requested_port)
        threading.Thread(target=self._watch_machine, name="toolbar", daemon=True).start()
        while not self.leaving:
            self._at_prompt.set()
            try:
                line = self.session.prompt(PROMPT)
            except KeyboardInterrupt:
                self.say("(Ctrl-C stops a command or a job; exit or Ctrl-D leaves)")
                continue                 # Ctrl-C at the prompt: a new prompt
            except EOFError:
                break                    # Ctrl-D leaves
            finally:
                self._at_prompt.clear()
            self.execute(line)
        self.leaving = True
        self.disconnect()
        return 0

    def _watch_machine(self) -> None:
        """Keep the toolbar's state and position current while the prompt waits
        (a jog or a home may still be running); commands query for themselves."""
        while not self.leaving:
            self._at_prompt.wait()
            machine = self.machine
            if machine is not None and not self.leaving:
                try:
                    self.last_status = machine.poll()
                except GalileoError:
                    self.last_status = None     # the toolbar says "no answer"
            time.sleep(TOOLBAR_REFRESH_S)

    def execute(self, line: str) -> None:
        try:
            words = shlex.split(line)
        except ValueError:               # an unbalanced quote: take the words as typed
            words = line.split()
        if not words:
            return
        name, arguments = words[0], words[1:]
        command = self.registry.get(name)
        if command is None and is_machine_line(line):
            command, arguments = self.registry.get(SEND), [line.strip()]
        elif command is not None and command.raw_arguments:
            arguments = line.split(None, 1)[1:]      # the rest as typed, quotes and all
        if command is None:
            self.unknown(name)
            return
        machine = self.machine
        if command.needs_machine and machine is None:
            self.say("not connected to a machine: type connect [PORT]")
            return
        try:
            if command.needs_machine:
                with machine.session():       # the toolbar's poller waits meanwhile
                    command.run(self, arguments)
            else:
                command.run(self, arguments)
        except PortGone as error:
            self.say(str(error))
            self.say("the port is gone: type connect to reconnect, then resume")
            self.disconnect()
        except MachineAlarm:
            pass                         # its alarm: line is on the screen already
        except GalileoError as error:
            self.say(str(error))
        except (KeyboardInterrupt, EOFError):
            self.say("cancelled")
            self._stop_safely()
            self.say(self._how_to_go_on(line.strip() if command.raw_arguments else name))
        if self.machine is not None:
            with self.machine.session():
                view = self.refresh_status()
                lines = self.machine.after_command(view)
            for text in lines:
                self.say(text)

    def _stop_safely(self) -> None:
        try:
            if self.machine is not None:
                with self.machine.session():
                    self.stop_if_moving()
        except GalileoError as error:
            self.say(f"could not stop the machine: {error}")

    def _how_to_go_on(self, name: str) -> str:
        """After a cancelled command (`name`, or a line for the machine as typed): how
        to start it again, and the job `resume` would continue (a job the command
        stopped, or one stopped before it)."""
        again = f"type {name} to start it again"
        try:
            entry = self.machine.pending() if self.machine is not None else None
        except GalileoError:
            entry = None
        if entry is None:
            return again
        go_on = f"resume to continue the stopped job of {entry.source}"
        return f"type {go_on}" if name == "resume" else f"{again}, or {go_on}"

    def unknown(self, word: str) -> None:
        closest = self.registry.closest(word)
        hint = f" Did you mean {closest}?" if closest else ""
        self.say(f"Unknown command!{hint} Type help for the list of commands.")


def _open_history(path: Path | None) -> History:
    if path is None:
        return InMemoryHistory()
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        path.touch(exist_ok=True)
    except OSError:
        return InMemoryHistory()      # a read-only home must not stop the console
    return FileHistory(str(path))
