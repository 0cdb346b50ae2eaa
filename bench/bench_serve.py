"""Does a job stream at the same pace with five browsers watching? (issue 34)

    python bench/bench_serve.py [FILE] [--speed S] [--rounds N] [--watchers W]

The same job on sim:// run through `galileo-cnc serve` (the real service, the real
uvicorn on loopback), with no page watching and with W pages on the event stream
(httpx streaming clients, each in a process of its own as a browser is, each an
EventSource: a TCP connection that reads every event). Rounds alternate 0 and W watchers so that a load that comes
and goes on the machine falls on both. Printed per run: the job's wall time (from the
POST that starts it to its `finished` in the history, asked every 50 ms as a script
would) and, per watcher, the largest gap between two events while the job ran (the
issue: at least one a second); at the end the median wall times and their ratio.

`--speed 1` (the default) is the issue's case, a machine at real time: a host that
keeps up finishes in the job's machine time whoever watches. `--speed 0` is the
instant machine: the job is then as fast as the host streams, so it shows what the
watchers cost the host itself.
"""

from __future__ import annotations

import argparse
import json
import multiprocessing
import os
import statistics
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path[:0] = [str(ROOT), str(ROOT / "tests"), str(ROOT / "tests" / "serve")]

import httpx  # noqa: E402

from galileo_cnc.sim.simulator import forget_named_machines  # noqa: E402
from serve_support import serving  # noqa: E402

DEFAULT = ROOT / "samples" / "square-and-circle.nc"


def watch(base: str, token: str, arrived) -> None:
    """A page, in a process of its own as a browser is (not sharing the server's
    interpreter): every event's arrival time (CLOCK_MONOTONIC, shared by the
    processes) put on `arrived`, until the job has ended; then None."""
    with httpx.Client(base_url=base, timeout=60,
                      headers={"authorization": f"Bearer {token}"}) as client:
        with client.stream("GET", "/api/events") as stream:
            for line in stream.iter_lines():
                if not line.startswith("data: "):
                    continue
                event = json.loads(line[6:])
                arrived.put((time.monotonic(), event["type"]))
                if event["type"] == "job" and event["job"]["result"] != "running":
                    break
    arrived.put(None)


def one_run(data: bytes, name: str, speed: float, watchers: int, pens: str) -> dict:
    forget_named_machines()
    with serving(f"sim://?speed={speed:g}") as (server, service, client):
        upload = client.post("/api/uploads", content=data,
                             headers={"x-filename": name}).json()
        plan = client.post("/api/plans", json={"upload": upload["id"], "pens": pens})
        if plan.status_code != 201:
            raise SystemExit(f"{name}: {plan.json()['error']}")
        plan_id = plan.json()["id"]
        base = f"http://127.0.0.1:{server.port}"
        spawn = multiprocessing.get_context("spawn")
        queues = [spawn.Queue() for _ in range(watchers)]
        pages = [spawn.Process(target=watch, args=(base, server.token, q), daemon=True)
                 for q in queues]
        for page in pages:
            page.start()
        arrived = [[q.get(timeout=30)] for q in queues]       # each has its first event
        began = time.monotonic()
        assert client.post("/api/jobs", json={"plan": plan_id}).status_code == 202
        answered: set[int] = set()
        while True:
            state = client.get("/api/state").json()
            prompt = state["prompt"]
            if prompt is not None and prompt["id"] not in answered:   # the pen is in
                client.post("/api/prompt", json={"id": prompt["id"], "answer": True})
                answered.add(prompt["id"])
            if state["activity"] is None and state["history"]:
                break
            time.sleep(0.05)
        wall = time.monotonic() - began
        record = state["history"][-1]
        for events, queue in zip(arrived, queues):
            while (event := queue.get(timeout=30)) is not None:
                events.append(event)
        for page in pages:
            page.join(10)
    gaps = []
    for events in arrived:
        times = [t for t, _ in events if t >= began]
        gaps.append(max(b - a for a, b in zip(times, times[1:])) if len(times) > 1 else None)
    return {"watchers": watchers, "wall_s": wall, "result": record["result"],
            "gaps": gaps, "prompts": len(answered),
            "events": [len(a) for a in arrived]}


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("file", nargs="?", default=str(DEFAULT),
                        help=f"a file to plot (default {DEFAULT.relative_to(ROOT)})")
    parser.add_argument("--speed", type=float, default=1.0,
                        help="sim:// speed (1 real time, 0 instant)")
    parser.add_argument("--rounds", type=int, default=3)
    parser.add_argument("--watchers", type=int, default=5)
    parser.add_argument("--pens", default="0.4",
                        help="the pens' widths in mm (default one pen: one prompt)")
    args = parser.parse_args(argv)
    os.environ["GALILEO_CNC_HOME"] = tempfile.mkdtemp(prefix="bench-serve-")
    os.environ["GALILEO_CNC_NO_PROBE"] = "1"
    path = Path(args.file)
    data = path.read_bytes()
    print(f"{path.name} on sim://?speed={args.speed:g}, {args.rounds} rounds of 0 and "
          f"{args.watchers} watchers")
    walls: dict[int, list[float]] = {0: [], args.watchers: []}
    for _ in range(args.rounds):
        for watchers in (0, args.watchers):
            run = one_run(data, path.name, args.speed, watchers, args.pens)
            walls[watchers].append(run["wall_s"])
            gaps = " ".join(f"{g:.2f}" for g in run["gaps"] if g is not None) or "-"
            print(f"  {watchers} watchers: wall {run['wall_s']:.2f} s ({run['prompts']} pen "
                  f"prompts answered) {run['result']}; largest event gap per "
                  f"watcher (s): {gaps}; events {run['events']}")
    quiet = statistics.median(walls[0])
    watched = statistics.median(walls[args.watchers])
    print(f"median wall: {quiet:.2f} s alone, {watched:.2f} s with {args.watchers} watchers: "
          f"ratio {watched / quiet:.3f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
