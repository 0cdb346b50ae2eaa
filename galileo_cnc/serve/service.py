"""The one owner of the machine behind `galileo-cnc serve`.

Every machine command (a job, a resume, home, unlock, feed, a jog) runs in one worker
thread, one at a time: a second is refused (`Busy`, HTTP 409), so one machine never
runs two jobs and a jog never crosses a job. The event loop never waits on the port.
A poller thread asks the machine where it stands (Machine.poll, as the console's
toolbar does) and publishes `status` events, and while a job runs `progress` events,
every TICK_S: each page hears of the job at least that often, however long one
command takes. Pages come and go; the job runs on until it ends, is stopped, or the
port is lost (the journal then keeps it for `resume`).

Planning is the same as the console's and plot's (plan.board_plan.plan_source), done
in the caller's thread (the app's thread pool): it needs no machine. A mill job
(`mill`: isolate, drill, cutout or all; docs/mill.md) is planned from the uploaded
board as `plot --mill` plans it (grbl/mill_plan.py) and run by a machine that runs
G-code (GRBL); its M0 pauses (a bit change, the probe) come to the page as a pen change.
"""

from __future__ import annotations

import asyncio
import dataclasses
import itertools
import json
import re
import threading
import time
from concurrent.futures import Future, ThreadPoolExecutor
from dataclasses import dataclass, field
from datetime import datetime, timezone
from pathlib import Path
from typing import Any, Callable
from xml.sax.saxutils import escape

from galileo_cnc.backends import Machine
from galileo_cnc.config.machine import MachineConfig, pen_widths_from_text
from galileo_cnc.config.userdirs import data_dir
from galileo_cnc.errors import GalileoError
from galileo_cnc.grbl.mill_job import mill_lines
from galileo_cnc.grbl.mill_plan import (DRY_RUN_NOTE, MILL_JOBS, mill_program, profile_mill,
                                        with_height_map, write_dry_run)
from galileo_cnc.machine.timing import duration_text
from galileo_cnc.plan.board_plan import BoardChoice, plan_source
from galileo_cnc.plan.feeds import machine_refusal
from galileo_cnc.plan.open_traces import open_traces
from galileo_cnc.plan.pipeline import PlanOptions
from galileo_cnc.preview.write import write_preview
from galileo_cnc.program.ops import NM_PER_MM
from galileo_cnc.serve.operator import Prompt, WebOperator
from galileo_cnc.serve.uploads import Upload, UploadStore
from galileo_cnc.stream.streamer import MachineReset
from galileo_cnc.transport.link import PortGone

#: how often pages hear where the machine stands (and how far a job is)
TICK_S = 0.25
#: plans kept for `start` (each holds its job's commands)
KEPT_PLANS = 8
HISTORY_KEPT = 100
#: a plan's modes (plan.pipeline.PlanOptions; auto picks one by the file)
PLAN_MODES = ("auto", "ink", "centre")


class Busy(GalileoError):
    """The machine is running something else (HTTP 409)."""


class NotFound(GalileoError):
    """No such plan or prompt (HTTP 404)."""


@dataclass
class Plan:
    """A planned upload, ready to start: what the page shows before it starts."""

    id: str
    upload: Upload
    planned: Any                    # plan.pipeline.PlannedFile
    config: MachineConfig
    options: dict
    preview: Path
    lines: list[str] = field(default_factory=list)

    def public(self) -> dict:
        job = self.planned.job
        return {"id": self.id, "upload": self.upload.id, "name": self.upload.name,
                "options": self.options, "lines": self.lines, "commands": len(job),
                "pen_changes": len(job.pen_changes),
                "preview": f"/api/plans/{self.id}/preview.svg"}


@dataclass
class MillPlan:
    """A mill job planned from an upload (grbl.mill_job.MillProgram), ready to start;
    no preview: its G-code is its plan (`convert --mill` writes it)."""

    id: str
    upload: Upload
    program: Any                    # grbl.mill_job.MillProgram
    mill: Any                       # config.mill.MillConfig: the tool (its height_map)
    options: dict
    lines: list[str] = field(default_factory=list)
    preview: Path | None = None

    def public(self) -> dict:
        sent, pauses = mill_lines(self.program.text)    # as GRBL is sent them
        return {"id": self.id, "upload": self.upload.id, "name": self.upload.name,
                "options": self.options, "lines": self.lines, "mill": self.options["mill"],
                "commands": len(sent), "pen_changes": len(pauses), "preview": None}


def _now_text() -> str:
    return datetime.now(timezone.utc).isoformat(timespec="seconds")


class MachineService:
    """`open_machine()` opens the machine (again, after a lost port)."""

    def __init__(self, open_machine: Callable[[], Machine], store: UploadStore | None = None,
                 *, folder: Path | None = None, tick_s: float = TICK_S):
        self._open_machine = open_machine
        self.machine: Machine = open_machine()
        self.config: MachineConfig = self.machine.config   # plans start from it (the feed)
        self.store = store if store is not None else UploadStore()
        self.folder = folder if folder is not None else data_dir() / "serve"
        self.tick_s = tick_s
        self._lock = threading.Lock()
        self._activity: str | None = None
        self._worker = ThreadPoolExecutor(1, thread_name_prefix="galileo-machine")
        self._subscribers: set[tuple[asyncio.AbstractEventLoop, asyncio.Queue]] = set()
        self._plans: dict[str, Plan] = {}
        self._plan_ids = itertools.count(1)
        self.operator: WebOperator | None = None
        self._jog_cancel: threading.Event | None = None   # the running jog's, for stop
        self._job: dict | None = None         # the running job: name, total, start
        self._prompt: Prompt | None = None
        self.lost = ""                        # why the port is gone ("" while it is not)
        self.resumable = self._pending_name()
        self.history: list[dict] = self._load_history()
        self.closing = threading.Event()
        self._views = 0
        self._view = self._ask_machine()      # a page's first state is the machine's
        self._poller = threading.Thread(target=self._poll, name="galileo-poller", daemon=True)
        self._poller.start()

    # ---- events ------------------------------------------------------------------------
    def subscribe(self) -> asyncio.Queue:
        """In the event loop: a queue of every event from now on."""
        queue: asyncio.Queue = asyncio.Queue(maxsize=1000)
        with self._lock:
            self._subscribers.add((asyncio.get_running_loop(), queue))
        return queue

    def unsubscribe(self, queue: asyncio.Queue) -> None:
        with self._lock:
            self._subscribers = {s for s in self._subscribers if s[1] is not queue}

    def publish(self, kind: str, data: dict) -> None:
        """From any thread, to every page."""
        event = {"type": kind, "t": time.time(), **data}
        with self._lock:
            subscribers = list(self._subscribers)
        for loop, queue in subscribers:
            try:
                loop.call_soon_threadsafe(_offer, queue, event)
            except RuntimeError:            # its loop has closed
                self.unsubscribe(queue)

    @property
    def subscribers(self) -> int:
        return len(self._subscribers)

    # ---- state ------------------------------------------------------------------------
    def snapshot(self) -> dict:
        """Everything a page shows, at once (GET /api/state; a new page's first event)."""
        view = self._view
        with self._lock:
            prompt = self._prompt.public() if self._prompt is not None else None
            activity = self._activity
        return {"machine": self.machine.describe() if not self.lost else self.lost,
                "kind": self.machine.kind, "state": self._state_text(view),
                "position": self._position(view), "activity": activity,
                "job": self._progress(), "prompt": prompt, "resumable": self.resumable,
                "feed_mm_s": self.config.feed_mm_s,
                "pens_mm": list(self.config.pen_widths_mm), "history": self.history[-20:]}

    def snapshot_position(self) -> dict:
        """Where the head stands, as last polled (a held jog's lines)."""
        view = self._view
        return {"state": self._state_text(view), "position": self._position(view)}

    def _state_text(self, view) -> str:
        if self.lost:
            return "port lost"
        return view.state if view is not None else "no answer"

    def _position(self, view) -> list[float] | None:
        operator = self.operator
        if operator is not None and operator.last is not None and \
                operator.last.position_nm is not None:
            return [nm / NM_PER_MM for nm in operator.last.position_nm]
        return list(view.position_mm) if view is not None and view.position_mm else None

    def _progress(self) -> dict | None:
        job, operator = self._job, self.operator
        if job is None or operator is None:
            return None
        p = operator.last
        confirmed, total = (p.confirmed, p.total) if p is not None else \
            (job["start"], job["total"])
        eta = None
        if p is not None and p.eta_s is not None:
            eta = max(0.0, p.eta_s - (time.monotonic() - operator.last_at))
        return {"name": job["name"], "confirmed": confirmed, "total": total,
                "percent": 100 * confirmed / max(total, 1), "eta_s": eta,
                "eta": duration_text(eta) if eta is not None else None,
                "elapsed_s": time.monotonic() - job["began"], "unit": job["unit"]}

    def _ask_machine(self):
        """Where the machine stands now (None: lost, or no answer)."""
        if self.lost:
            return None
        try:
            return self.machine.poll()
        except GalileoError:
            return None

    def _set_view(self, view, asked_at: int | None = None) -> Any:
        """The view pages see; a poll's (`asked_at`: the views set when it began) only
        when no fresher one came meanwhile: a machine busy with a command (GRBL) answers
        a poll with its view from before, which must not hide the one taken as the
        command ended."""
        with self._lock:
            if asked_at is None or asked_at == self._views:
                self._view = view
                self._views += 1
            return self._view

    def _poll(self) -> None:
        while not self.closing.wait(self.tick_s):
            asked_at = self._views
            view = self._set_view(self._ask_machine(), asked_at)
            self.publish("status", {"state": self._state_text(view),
                                    "position": self._position(view),
                                    "activity": self._activity})
            progress = self._progress()
            if progress is not None:
                self.publish("progress", progress)

    # ---- one command at a time ------------------------------------------------------------
    def _begin(self, activity: str) -> None:
        with self._lock:
            if self._activity is not None:
                raise Busy(f"the machine is busy ({self._activity}): stop it first, or wait")
            if self.lost and activity != "resume":
                raise Busy(f"{self.lost}: the job can continue with resume once the "
                           f"machine is back")
            self._activity = activity
        self.publish("activity", {"activity": activity})

    def _end(self) -> None:
        with self._lock:
            self._activity = None
        self.publish("activity", {"activity": None})

    def _submit(self, activity: str, work: Callable[[], Any]) -> Future:
        """`work` in the machine's thread; Busy when something else runs there."""
        self._begin(activity)

        def run():
            try:
                with self.machine.session():
                    return work()
            except PortGone as gone:
                self._port_lost(gone)
                raise
            except GalileoError as error:
                self.publish("failure", {"text": str(error)})
                raise
            finally:
                # where the machine stands now, before pages hear it is free
                self._set_view(self._ask_machine())
                self._end()
        return self._worker.submit(run)

    @property
    def activity(self) -> str | None:
        return self._activity

    # ---- plans --------------------------------------------------------------------------
    def plan(self, upload_id: str, *, pens: str = "", mode: str = "auto", side: str = "top",
             offset: str = "auto", allow_open: bool = False, mill: str = "",
             mill_set: dict | None = None, accept_shorts: bool = False) -> Plan:
        """Plan an upload (in the caller's thread: seconds on a large board) and draw
        its preview; GalileoError says why it cannot be plotted. `mill`: a mill job
        instead (plan_mill)."""
        if not upload_id:
            raise NotFound("plan: which upload? send {\"upload\": ID}, the id POST "
                           "/api/uploads answered")
        upload = self.store.get(upload_id)
        path = self.store.path(upload)
        if mill:
            return self.plan_mill(upload, mill, side=side, mill_set=mill_set or {},
                                  accept_shorts=accept_shorts)
        config = self.config
        if mode not in PLAN_MODES:
            raise GalileoError(f"mode: expected {', '.join(PLAN_MODES[:-1])} or "
                               f"{PLAN_MODES[-1]}, got {mode!r}")
        if side not in ("top", "bottom"):
            raise GalileoError(f"side: expected top or bottom, got {side!r}")
        try:
            if pens:
                config = config.replace(pen_widths_mm=pen_widths_from_text(pens))
        except GalileoError as error:
            raise GalileoError(_as_field(str(error))) from None
        board = BoardChoice(side=side) if upload.kind == "board" else None
        try:
            planned = plan_source(path, config, offset or "auto", board=board,
                                  options=PlanOptions(mode=mode or "auto"))
            if planned.ink is not None and not allow_open and \
                    (summary := open_traces(planned.ink)) is not None:
                raise GalileoError(f"{summary.text()}; plotting it anyway leaves them out "
                                   f"(allow open traces)")
            refused = machine_refusal(planned.program, config, self.machine.feed_refusal)
            if refused is not None:
                raise GalileoError(refused)
        except GalileoError as error:
            raise GalileoError(_as_field(str(error).replace(str(path), upload.name))) \
                from None
        options = {"pens": pens, "mode": planned.mode,
                   "side": side if board is not None else None, "offset": offset}
        return self._plan_made(upload, planned, config, options, path)

    def _plan_made(self, upload: Upload, planned, config: MachineConfig, options: dict,
                   path: Path, notes: tuple[str, ...] = ()) -> Plan:
        """The Plan of `planned` (from `path`, the upload or a dry run's G-code), its
        preview drawn and its lines named as the page knows the upload."""
        plan_id = f"p{next(self._plan_ids)}"
        preview = self.folder / "previews" / f"{plan_id}.svg"
        preview.parent.mkdir(parents=True, exist_ok=True)
        info = write_preview(planned, config, preview)
        # its title names the file as the client knows it, not where the server keeps it
        svg = re.sub(r"<title>.*?</title>", f"<title>{escape(upload.name)}: galileo-cnc "
                     f"preview (work mm)</title>", preview.read_text(encoding="utf-8"), 1)
        preview.write_text(svg, encoding="utf-8")
        lines = [line for line in (*notes, getattr(planned, "side_line", ""),
                                   *getattr(planned, "feed_warnings", ()),
                                   f"offset {planned.offset_nm[0] / NM_PER_MM:.3f}, "
                                   f"{planned.offset_nm[1] / NM_PER_MM:.3f} mm",
                                   info.summary().split(" (open it")[0]) if line]
        plan = Plan(plan_id, upload, planned, config, options, preview,
                    [line.replace(str(path), upload.name) for line in lines])
        return self._keep(plan)

    def plan_mill(self, upload: Upload, job: str, *, side: str = "top",
                  mill_set: dict | None = None, accept_shorts: bool = False
                  ) -> MillPlan | Plan:
        """A mill job of an uploaded board (or one file: isolate), its tool the profile's
        [mill] with `mill_set` ({"passes": 2}, the table's keys) over it (on a machine
        that runs no G-code, its dry run: a Plan); GalileoError says why not: a key,
        islands closer than the cut (listed in mm)."""
        from galileo_cnc.config.mill import MillConfig
        if job not in MILL_JOBS:
            raise GalileoError(f"mill: expected {', '.join(MILL_JOBS[:-1])} or "
                               f"{MILL_JOBS[-1]}, got {job!r}")
        if side not in ("top", "bottom"):
            raise GalileoError(f"side: expected top or bottom, got {side!r}")
        if not isinstance(mill_set, dict):
            raise GalileoError("mill_set: expected an object of [mill] keys, e.g. "
                               "{\"passes\": 2, \"tool\": \"endmill\"}")
        path = self.store.path(upload)
        choice = BoardChoice(side=side) if upload.kind == "board" else None
        try:
            mill = MillConfig.from_table(mill_set, "mill_set", base=profile_mill(
                getattr(self.machine, "config_path", None)))
            program, notes, summary = mill_program(str(path), job, mill, choice,
                                                   accept_shorts=accept_shorts)
        except GalileoError as error:        # the options as the API names them
            text = str(error).replace(str(path), upload.name).replace(
                "--accept-shorts", "accept_shorts: true").replace("--mill-set", "mill_set")
            raise GalileoError(text) from None
        # the job's name as the page knows the upload, not where the server keeps it
        program = dataclasses.replace(program, name=f"{upload.name} (mill {job})")
        lines = [f"{upload.name} (mill {job}): {summary}", *(f"note: {note}" for note in notes)]
        options = {"mill": job, "side": side if choice is not None else None,
                   "mill_set": mill_set, "accept_shorts": accept_shorts}
        if not self.machine.runs_mill:
            return self._dry_run_plan(upload, program, options, lines)
        return self._keep(MillPlan(f"p{next(self._plan_ids)}", upload, program, mill, options,
                                   [line.replace(str(path), upload.name) for line in lines]))

    def _dry_run_plan(self, upload: Upload, program, options: dict, lines: list[str]) -> Plan:
        """A mill job on a machine that runs no G-code (sim://, our firmware): the dry run
        `plot --mill` makes there, planned as an uploaded G-code file is, so the page
        shows its preview and starts it as any plot."""
        gcode = self.folder / "dry-runs" / f"{upload.id}-{options['mill']}.nc"
        pauses = write_dry_run(program, gcode)
        try:
            planned = plan_source(gcode, self.config, "auto")
            refused = machine_refusal(planned.program, self.config, self.machine.feed_refusal)
            if refused is not None:
                raise GalileoError(refused)
        except GalileoError as error:
            raise GalileoError(_as_field(str(error).replace(str(gcode), upload.name))) \
                from None
        notes = (f"note: {self.machine.port_name} runs galileo-cnc firmware, not G-code: "
                 f"{DRY_RUN_NOTE}", *lines, *pauses)
        return self._plan_made(upload, planned, self.config, {**options, "dry_run": True},
                               gcode, notes)

    def _keep(self, plan):
        with self._lock:
            self._plans[plan.id] = plan
            for old in list(self._plans)[:-KEPT_PLANS]:
                preview = self._plans.pop(old).preview
                if preview is not None:
                    preview.unlink(missing_ok=True)
        return plan

    def get_plan(self, plan_id: str) -> Plan:
        plan = self._plans.get(plan_id)
        if plan is None:
            raise NotFound(f"no plan {plan_id!r}: plan the upload again")
        return plan

    # ---- jobs -----------------------------------------------------------------------------
    def start(self, plan_id: str) -> Future:
        plan = self.get_plan(plan_id)
        if isinstance(plan, MillPlan):
            return self._submit("job", lambda: self._run_mill(plan))
        return self._submit("job", lambda: self._run_job(plan))

    def resume(self) -> Future:
        if not self.lost and self.machine.interrupted_mill() is None:
            self.machine.pending()      # GalileoError at once: none to resume, and why
        return self._submit("resume", self._resume)

    def stop(self) -> bool:
        """From any thread: stop the running job or jog (the machine ramps down);
        False when neither runs."""
        jogging = self._jog_cancel
        if jogging is not None:
            jogging.set()
            return True
        operator = self.operator
        if operator is None:
            return False
        operator.request_stop()            # a pen-change wait ends too
        self.machine.stop()
        return True

    def answer(self, prompt_id: int, answer: bool) -> None:
        operator = self.operator
        if operator is None or not operator.answer(prompt_id, answer):
            raise NotFound(f"no open question {prompt_id}")

    def _set_prompt(self, prompt: Prompt | None) -> None:
        with self._lock:
            self._prompt = prompt
        self.publish("prompt", {"prompt": prompt.public() if prompt else None})

    def _run_job(self, plan: Plan) -> dict:
        machine = self.machine
        machine.use_config(plan.config)       # its pens: the journal keeps them for resume
        job = machine.prepare(plan.planned, plan.config)
        return self._stream(plan.upload.name, job, lambda op: machine.run_job(job, op),
                            first=job.estimate_line())

    def _run_mill(self, plan: MillPlan) -> dict:
        """The mill job; with [mill] height_map the surface probed first, the page asked
        to clip the probe on and take it off (confirm prompts)."""
        machine = self.machine
        operator = WebOperator(self.publish, self._set_prompt)
        program = plan.program
        if plan.mill.height_map:
            self.operator = operator            # its prompts are answered through the API
            try:
                program = with_height_map(machine, program, plan.mill, operator.confirm,
                                          operator.say)
            finally:
                self.operator = None
        job = machine.prepare_mill(program)
        return self._stream(program.name, job, lambda op: machine.run_job(job, op),
                            first=job.estimate_line(), operator=operator)

    def _resume(self) -> dict:
        if self.lost:
            self._reconnect()
        machine = self.machine
        pending = self.machine.interrupted_mill()
        if pending is not None:                   # a mill job: its own journal
            resumption = machine.plan_mill_resume(pending)
            return self._went_on(pending[1].name, resumption)
        entry = machine.pending()                 # GalileoError: none, and why
        resumption = machine.plan_resume(entry)
        return self._went_on(self._shown_name(entry.source), resumption)

    def _went_on(self, name: str, resumption) -> dict:
        """A resumption said, and the rest run (its position found first)."""
        machine = self.machine
        self.publish("message", {"text": f"{name}: {resumption.why}"})
        if resumption.job is None:
            self.publish("message", {"text": resumption.nothing_left})
            self.resumable = self._pending_name()
            return {"result": "nothing left"}
        return self._stream(name, resumption.job, lambda op: machine.resume(resumption, op))

    def _stream(self, name: str, job, run, first: str = "", operator=None) -> dict:
        operator = operator or WebOperator(self.publish, self._set_prompt)
        self._job = {"name": name, "total": job.total, "start": job.start, "unit": job.unit,
                     "began": time.monotonic()}
        self.operator = operator
        record = {"id": len(self.history) + 1, "file": name, "started": _now_text(),
                  "result": "running", "elapsed_s": None, "confirmed": job.start,
                  "total": job.total, "unit": job.unit}
        self.publish("job", {"job": record})
        if first:
            operator.say(first)
        began = time.monotonic()
        try:
            result = run(operator)
            if result is None:                    # the user could not set the position
                record["result"] = "not started: the position was not found"
            elif result.completed:
                record["result"] = "finished"
                operator.say(f"process has finished in {duration_text(result.elapsed_s)}"
                             f"{'; ' + result.where if result.where else ''}")
            else:
                how = f"; {result.held}" if result.held else ""
                record["result"] = f"stopped: {result.reason}{how}"
                operator.say(f"job stopped after {result.confirmed} of {result.total} "
                             f"{result.unit}{how}; resume continues it")
            if result is not None:
                record["confirmed"] = job.start + result.confirmed
        except PortGone as gone:
            record["result"] = f"port lost: {gone}"
            raise
        except MachineReset as reset:
            record["result"] = f"machine reset: {reset}"
            raise
        except GalileoError as error:
            record["result"] = f"failed: {error}"
            raise
        finally:
            record["elapsed_s"] = round(time.monotonic() - began, 1)
            if self.operator is operator and operator.last is not None:
                record["confirmed"] = max(record["confirmed"], operator.last.confirmed)
            self.operator = None
            self._job = None
            self.resumable = self._pending_name()
            self._record(record)
        return record

    # ---- machine commands -----------------------------------------------------------------
    def home(self) -> Future:
        return self._submit("home", lambda: self._said(self.machine.home))

    def unlock(self) -> Future:
        return self._submit("unlock", lambda: self._said(self.machine.unlock))

    def set_feed(self, mm_s: float) -> Future:
        def work():
            refused = self.machine.feed_refusal(self.config, mm_s)
            if refused is not None:
                raise GalileoError(f"feed {mm_s:g} mm/s {refused}")
            config = self.config.replace(feed_mm_s=mm_s)
            note = self.machine.set_feed(config, mm_s)
            self.machine.use_config(config)
            self.config = config
            text = f"feed {mm_s:g} mm/s{'; ' + note if note else ''}"
            self.publish("message", {"text": text})
            return [text]
        return self._submit("feed", work)

    def _said(self, command) -> list[str]:
        lines: list[str] = []

        def say(text: str) -> None:
            lines.append(text)
            self.publish("message", {"text": text})
        command(say)
        return lines

    def jog_session(self, axis: int, direction: int, cancelled: threading.Event,
                    distance_mm: float | None = None) -> Future:
        from galileo_cnc.serve.jog import jog

        def work():
            self._jog_cancel = cancelled
            try:
                return jog(self.machine, self.config, axis, direction, cancelled,
                           distance_mm, self.publish)
            finally:
                self._jog_cancel = None
        return self._submit("jog", work)

    # ---- a lost port, the journal, the history -----------------------------------------------
    def _port_lost(self, gone: PortGone) -> None:
        self.lost = f"the machine's port is gone ({gone})"
        self.publish("failure", {"text": f"{self.lost}; once the machine stands still, "
                                       f"resume continues the job"})

    def _reconnect(self) -> None:
        try:
            self.machine.close()
        except Exception:               # the old port is gone: closing it may fail too
            pass
        self.machine = self._open_machine()
        self.machine.use_config(self.config)
        self.lost = ""

    def _pending_name(self) -> str | None:
        try:
            mill = self.machine.interrupted_mill()
            if mill is not None:
                return mill[1].name
            entry = self.machine.pending()
        except GalileoError:
            return None
        return self._shown_name(entry.source)

    def _shown_name(self, source: str) -> str:
        """An upload's name as the client gave it (the journal has our name for it)."""
        stem = Path(source).stem
        try:
            return self.store.get(stem).name
        except GalileoError:
            return Path(source).name

    def _history_path(self) -> Path:
        return self.folder / "history.json"

    def _load_history(self) -> list[dict]:
        try:
            return json.loads(self._history_path().read_text())[-HISTORY_KEPT:]
        except (OSError, ValueError):
            return []

    def _record(self, record: dict) -> None:
        self.history = [*self.history, record][-HISTORY_KEPT:]
        try:
            self.folder.mkdir(parents=True, exist_ok=True)
            self._history_path().write_text(json.dumps(self.history, indent=1))
        except OSError as error:
            self.publish("failure", {"text": f"the job history was not saved: {error}"})
        self.publish("job", {"job": record})

    def close(self) -> None:
        """The server ends: a running job is stopped (the journal keeps it)."""
        self.closing.set()
        self.stop()
        self._worker.shutdown(wait=True)
        self.machine.close()


def _as_field(text: str) -> str:
    """A planning error as the API's client knows the option: `mode`, not `--mode`
    (the command line's name, which the planner's messages use); a way out that only
    the command line has is said to be the command line's."""
    text = re.sub(r"^--(pens|mode|offset|side)\b", r"\1", text)
    text = re.sub(r"--fit scales it to the travel \(or --scale F(, --rotate 90)?\)",
                  "the page cannot scale a job: `galileo-cnc plot --fit` scales it to the "
                  "travel", text)
    text = re.sub(r"--layer FILE=other leaves one out",
                  "upload the board without the ones not wanted (or `galileo-cnc plot "
                  "--layer FILE=other`)", text)
    return re.sub(r"^config: pens widths_mm must be", "pens: expected", text)


def _offer(queue: asyncio.Queue, event: dict) -> None:
    if not queue.full():                    # a page that reads nothing loses events
        queue.put_nowait(event)
