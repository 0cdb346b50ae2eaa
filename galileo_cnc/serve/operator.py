"""The page as a job's Operator (backends/base.py): what the job says and how far it
is go out as events; a pen change or a question waits for an answer from any page
(POST /api/prompt), or for the stop button.
"""

from __future__ import annotations

import itertools
import threading
import time

from galileo_cnc.stream.streamer import PenChange, Progress, StreamAborted

#: how often a waiting prompt looks for a stop
_WAIT_POLL_S = 0.1
_ids = itertools.count(1)


class Prompt:
    """One question to the person at the machine, answered once."""

    def __init__(self, kind: str, text: str):
        self.id = next(_ids)
        self.kind = kind            # "pen": put the pen in; "confirm": make it so, or not
        self.text = text
        self.answer: bool | None = None
        self.answered = threading.Event()

    def public(self) -> dict:
        return {"id": self.id, "kind": self.kind, "text": self.text}


class WebOperator:
    """`publish(kind, data)` sends an event to every page; `on_prompt(prompt | None)`
    shows or clears the question in the service's state."""

    def __init__(self, publish, on_prompt):
        self.publish = publish
        self.on_prompt = on_prompt
        self.stop_requested = threading.Event()
        self.last: Progress | None = None
        self.last_at = 0.0
        self.prompt: Prompt | None = None

    # ---- from the API ----------------------------------------------------------------
    def request_stop(self) -> None:
        self.stop_requested.set()

    def answer(self, prompt_id: int, answer: bool) -> bool:
        """False when `prompt_id` is not the open question."""
        prompt = self.prompt
        if prompt is None or prompt.id != prompt_id:
            return False
        prompt.answer = answer
        prompt.answered.set()
        return True

    # ---- the Operator, called by the job in the machine's thread ------------------------
    def say(self, text: str) -> None:
        self.publish("message", {"text": text})

    def progress(self, p: Progress) -> None:
        self.last = p
        self.last_at = time.monotonic()

    def pen_change(self, change: PenChange) -> None:
        if not self._ask("pen", change.prompt):
            raise StreamAborted("stopped by the user")

    def confirm(self, question: str) -> bool:
        return self._ask("confirm", question)

    def _ask(self, kind: str, text: str) -> bool:
        """True when answered yes; False when answered no or stopped."""
        prompt = Prompt(kind, text)
        self.prompt = prompt
        self.on_prompt(prompt)
        try:
            while not (self.stop_requested.is_set() or prompt.answered.wait(_WAIT_POLL_S)):
                pass
        finally:
            self.prompt = None
            self.on_prompt(None)
        return bool(prompt.answer) and not self.stop_requested.is_set()
