"""Secure by default (issue 34): every route of the application, walked from its own
route table, refuses a request without the token, with a wrong one, and from a
foreign Origin, and not one of them changes anything: no upload kept, no plan made,
no job run, the head where it was, the journal as it was."""

from __future__ import annotations

import httpx
import pytest

from galileo_cnc.serve.uploads import MAX_UPLOAD_BYTES

from serve_support import GERBER, board_zip, wait_for

def _world(service, client) -> dict:
    """What a request could change."""
    state = client.get("/api/state").json()
    uploads = sorted(p.name for p in service.store.folder.glob("*")) \
        if service.store.folder.exists() else []
    journal = sorted(p.read_bytes() for p in service.folder.parent.rglob("journal*.json"))
    return {"position": state["position"], "history": state["history"], "uploads": uploads,
            "plans": len(service._plans), "activity": state["activity"],
            "feed": state["feed_mm_s"], "journal": journal}


def _requests(app, plan_id: str, upload_id: str):
    """(method, path, body) for every method of every route, with bodies that would
    do something if let through."""
    bodies = {"/api/uploads": GERBER, "/api/plans": {"upload": upload_id},
              "/api/jobs": {"plan": plan_id}, "/api/prompt": {"id": 1, "answer": True},
              "/api/jog": {"axis": "x", "direction": 1, "distance_mm": 1},
              "/api/feed": {"mm_s": 7}}
    for route in app.routes:
        path = route.path.replace("{plan_id}", plan_id)
        for method in sorted(route.methods):
            yield method, path, bodies.get(route.path, {} if method == "POST" else None)


def _send(bare: httpx.Client, method: str, path: str, body, headers: dict) -> httpx.Response:
    if isinstance(body, bytes):
        return bare.request(method, path, content=body, headers=headers)
    return bare.request(method, path, json=body, headers=headers)


def test_every_route_refuses_without_the_token_a_wrong_one_and_a_foreign_origin(served):
    server, service, client = served
    upload_id = client.post("/api/uploads", content=GERBER).json()["id"]
    plan_id = client.post("/api/plans", json={"upload": upload_id}).json()["id"]
    before = _world(service, client)
    base = f"http://127.0.0.1:{server.port}"
    right = {"authorization": f"Bearer {server.token}"}
    cookie = {"cookie": f"galileo_cnc_token_{server.port}={server.token}"}
    ways = {"no token": ({}, 401), "wrong token": ({"authorization": "Bearer nope"}, 401),
            "wrong cookie": ({"cookie": f"galileo_cnc_token_{server.port}=nope"}, 401),
            "foreign origin": ({**right, "origin": "http://evil.example"}, 403),
            "foreign origin, cookie": ({**cookie, "origin": "http://evil.example"}, 403),
            "null origin": ({**right, "origin": "null"}, 403),
            "cross-site fetch": ({**cookie, "sec-fetch-site": "cross-site"}, 403),
            "another port": ({**right, "origin": "http://127.0.0.1:1"}, 403)}
    walked = set()
    with httpx.Client(base_url=base) as bare:       # keeps no cookie: none is set
        for method, path, body in _requests(server.app.app, plan_id, upload_id):
            walked.add(path)
            for way, (headers, status) in ways.items():
                answer = _send(bare, method, path, body, headers)
                assert answer.status_code == status, (method, path, way, answer.text)
    assert {"/", "/api/events", "/api/jog", "/api/jobs", "/api/uploads"} <= walked
    assert len(walked) == len(server.app.app.routes) >= 17
    assert _world(service, client) == before
    # the same requests with the token do change things (the walk could catch them)
    assert client.post("/api/feed", json={"mm_s": 7}).status_code == 200
    assert client.post("/api/jog", json={"axis": "x", "direction": 1,
                                         "distance_mm": 1}).status_code == 200
    wait_for(client, lambda s: s["position"] != before["position"])     # the next poll


def test_the_printed_url_sets_a_cookie_and_the_page_needs_it(served):
    server, service, client = served
    base = f"http://127.0.0.1:{server.port}"
    assert httpx.get(base + "/").status_code == 401
    assert httpx.get(base + "/?token=wrong").status_code == 401
    # a page of another name that resolves here (DNS rebinding): refused by its Host
    rebound = httpx.get(server.url, headers={"host": f"evil.example:{server.port}"})
    assert rebound.status_code == 403 and "(Host)" in rebound.json()["error"]
    assert httpx.get(f"http://localhost:{server.port}/").status_code == 401   # a name of ours
    # the URL's token opens the page only: a command in a URL is kept in histories
    token = server.url.split("token=")[1]
    assert httpx.post(f"{base}/api/home?token={token}").status_code == 401
    first = httpx.get(server.url)
    assert first.status_code == 303 and first.headers["location"] == "/"
    set_cookie = first.headers["set-cookie"]
    assert "HttpOnly" in set_cookie and "SameSite=Strict" in set_cookie
    with httpx.Client(base_url=base, cookies=first.cookies) as browser:
        page = browser.get("/")
        assert page.status_code == 200 and "<title>galileo-cnc</title>" in page.text
        assert "frame-ancestors 'none'" in page.headers["content-security-policy"]
        assert browser.get("/app.js").status_code == 200
        # the page's own Origin may change state
        same = browser.post("/api/feed", json={"mm_s": 6}, headers={"origin": base})
        assert same.status_code == 200


def test_a_job_too_big_names_no_option_the_api_lacks(served):
    server, service, client = served
    upload = client.post("/api/uploads", content=b"G21 G90\nG1 X5000 Y10 F300\n",
                         headers={"x-filename": "far.nc"}).json()["id"]
    answer = client.post("/api/plans", json={"upload": upload})
    assert answer.status_code == 422, answer.text
    error = answer.json()["error"]
    assert "the job is 5000.0 mm wide" in error and "--scale" not in error, error
    assert "the page cannot scale a job: `galileo-cnc plot --fit` scales it" in error


def test_an_upload_keeps_its_name_in_utf_8(served):
    # sent in UTF-8 (curl), or percent-escaped (the page: a header holds Latin-1 only)
    server, service, client = served
    for sent in ("café.gbr".encode("utf-8"), b"caf%C3%A9.gbr"):
        named = client.post("/api/uploads", content=GERBER, headers={"x-filename": sent})
        assert named.json()["name"] == "café.gbr", sent


def test_uploads_are_checked_by_content_and_named_by_the_server(served, tmp_path):
    server, service, client = served
    kept = client.post("/api/uploads", content=GERBER,
                       headers={"x-filename": "../../../etc/passwd"}).json()
    assert kept["kind"] == "gerber" and kept["name"] == "passwd"
    assert [p.name for p in service.store.folder.iterdir()] and \
        all(p.stem == kept["id"] for p in service.store.folder.iterdir())
    board = client.post("/api/uploads", content=board_zip(tmp_path),
                        headers={"x-filename": "board.zip"}).json()
    assert board["kind"] == "board" and board["sides"] == ["top", "bottom"]
    refused = {
        "binary": (b"\x7fELF\x02\x01\x01" + bytes(range(256)), 415),
        "drill alone": (b"M48\nMETRIC\nT1C0.800\n%\nT1\nX1.0Y1.0\nM30\n", 415),
        "text": (b"dear plotter,\nplease draw a cat\n", 415),
        "zip without a board": (b"PK\x03\x04" + bytes(40), 415),
        "empty": (b"", 400),
    }
    for what, (body, status) in refused.items():
        answer = client.post("/api/uploads", content=body, headers={"x-filename": "f.gbr"})
        assert answer.status_code == status, (what, answer.text)
        assert answer.json()["error"]
    large = client.post("/api/uploads", content=b"G1 X1\n" * (MAX_UPLOAD_BYTES // 6 + 1))
    assert large.status_code == 413
    assert len(list(service.store.folder.glob("*.json"))) == 2       # the two kept
    # ids are the server's: nothing else names a file
    assert client.post("/api/plans", json={"upload": "../uploads/x"}).status_code == 404
    # and what comes back names the file as the client does, not where it is kept
    plan = client.post("/api/plans", json={"upload": board["id"], "mode": "centre"}).json()
    svg = client.get(plan["preview"]).text
    assert "<title>board.zip:" in svg and str(service.store.folder) not in svg


@pytest.mark.parametrize("what", ["job", "jog"])
def test_one_machine_never_runs_two_things(served, what, tmp_path):
    server, service, client = served
    upload_id = client.post("/api/uploads", content=board_zip(tmp_path)).json()["id"]
    plan_id = client.post("/api/plans", json={"upload": upload_id,
                                              "mode": "centre"}).json()["id"]
    assert client.post("/api/jobs", json={"plan": plan_id}).status_code == 202
    # the job waits for its first pen: the machine is the job's
    prompt = wait_for(client, lambda s: s["prompt"])["prompt"]
    assert prompt["kind"] == "pen"
    again = {"job": lambda: client.post("/api/jobs", json={"plan": plan_id}),
             "jog": lambda: client.post("/api/jog", json={"axis": "x", "direction": 1})}
    answer = again[what]()
    assert answer.status_code == 409 and "busy (job)" in answer.json()["error"]
    assert client.post("/api/home").status_code == 409
    while (prompt := wait_for(client, lambda s: s["prompt"] or s["activity"] is None)
           ["prompt"]) is not None:
        assert client.post("/api/prompt", json={"id": prompt["id"],
                                                "answer": True}).status_code == 200
        wait_for(client, lambda s, i=prompt["id"]: (s["prompt"] or {}).get("id") != i)
    history = client.get("/api/history").json()["history"]
    assert [h["result"] for h in history] == ["finished"]
    nothing = client.post("/api/resume")
    assert nothing.status_code == 422 and "no interrupted job" in nothing.json()["error"]


def test_serve_listens_on_loopback_unless_told():
    from galileo_cnc.cli.main import build_parser
    from galileo_cnc.errors import GalileoError
    from galileo_cnc.serve.server import parse_listen

    args = build_parser().parse_args(["serve", "--port", "sim://"])
    assert parse_listen(args.listen) == ("127.0.0.1", 8765) and args.port == "sim://"
    assert parse_listen("0.0.0.0:80") == ("0.0.0.0", 80)
    assert parse_listen("[::1]:0") == ("::1", 0)
    for wrong in ("8765", "localhost:http", "host:99999"):
        with pytest.raises(GalileoError, match="--listen: expected HOST:PORT"):
            parse_listen(wrong)


def test_wrong_options_are_refused_naming_the_option_in_mm(served):
    """What a client gets wrong is answered 4xx with the option named as the API names
    it (not the command line's --option), in mm; nothing that looks like a path is
    taken, and the server stays up for the next request."""
    server, service, client = served
    upload = client.post("/api/uploads", content=GERBER).json()["id"]
    refused = {
        ("/api/plans", '{"upload": "%s", "mode": "fast"}'):
            "mode: expected auto, ink or centre, got 'fast'",
        ("/api/plans", '{"upload": "%s", "pens": "abc"}'): "pens: expected widths in mm",
        ("/api/plans", '{"upload": "%s", "pens": "NaN"}'): "pens: expected 1 to 8 widths",
        # a pen of 1 nm (rounding to 0 once made a 500), or 1 um (hours to plan)
        ("/api/plans", '{"upload": "%s", "pens": "1e-9"}'):
            "pens: expected 1 to 8 widths from 0.05 to 5 mm",
        ("/api/plans", '{"upload": "%s", "pens": "0.001"}'):
            "pens: expected 1 to 8 widths from 0.05 to 5 mm",
        ("/api/plans", '{"upload": "%s", "pens": "-1"}'):
            "pens: expected 1 to 8 widths from 0.05 to 5 mm, got -1",
        ("/api/plans", '{"upload": "%s", "offset": "1e20,0"}'):
            "offset: expected auto, none or X,Y in mm",
        ("/api/plans", '{"upload": "%s", "offset": "/etc/passwd"}'):
            "offset: expected auto, none or X,Y in mm",
        ("/api/plans", '{}'): "plan: which upload?",
        ("/api/plans", '{"upload": null}'): "plan: which upload?",
        ("/api/nothing", '{}'): "POST /api/nothing: Not Found",
        # a misspelt option is not planned without, unsaid
        ("/api/plans", '{"upload": "%s", "pen": "0.8"}'): "plan: unknown field 'pen'; the fields",
        ("/api/feed", '{"mm_s": "nan"}'): 'feed: expected {"mm_s": N}, a number of mm/s',
        ("/api/feed", '{"mm_s": NaN}'): 'feed: expected {"mm_s": N}, a number of mm/s',
        ("/api/feed", '{"mm_s": Infinity}'): 'feed: expected {"mm_s": N}, a number of mm/s',
        ("/api/feed", '{"mm_s": 0}'): "feed 0 mm/s refused: the machine runs",
        # a string or a boolean is no number, as for the feed
        ("/api/jog", '{"axis": "x", "direction": 1, "distance_mm": "5"}'):
            'jog: distance_mm must be a number of mm, got "5"',
        ("/api/jog", '{"axis": "x", "direction": true, "distance_mm": 1}'):
            'jog: expected {"axis": "x"|"y"|"z", "direction": 1|-1}',
    }
    for (path, body), text in refused.items():
        answer = client.post(path, content=body.replace("%s", upload),
                             headers={"content-type": "application/json"})
        assert answer.status_code in (404, 422), (path, body, answer.text)
        assert answer.json()["error"].startswith(text), (path, body, answer.text)
    state = client.get("/api/state").json()
    assert state["activity"] is None and state["feed_mm_s"] == service.config.feed_mm_s
    # a single file has no side: the plan does not claim one
    plan = client.post("/api/plans", json={"upload": upload, "side": "bottom"}).json()
    assert plan["options"]["side"] is None


def test_a_job_survives_the_page_that_started_it(served, tmp_path):
    """The page that started a job goes away (its event stream closes) while the job
    waits for a pen: the job waits on, and another page finishes it."""
    server, service, client = served
    upload_id = client.post("/api/uploads", content=board_zip(tmp_path)).json()["id"]
    plan_id = client.post("/api/plans", json={"upload": upload_id,
                                              "mode": "centre"}).json()["id"]
    base = f"http://127.0.0.1:{server.port}"
    with httpx.Client(base_url=base, headers=client.headers, timeout=10) as page:
        with page.stream("GET", "/api/events") as events:
            assert next(events.iter_lines()).startswith("event: state")
            assert page.post("/api/jobs", json={"plan": plan_id}).status_code == 202
            first = wait_for(client, lambda s: s["prompt"])["prompt"]
    wait_for(client, lambda s: service.subscribers == 0)           # the page is gone
    state = client.get("/api/state").json()
    assert state["activity"] == "job" and state["prompt"] == first  # the job waits on
    while (prompt := wait_for(client, lambda s: s["prompt"] or s["activity"] is None)
           ["prompt"]) is not None:
        client.post("/api/prompt", json={"id": prompt["id"], "answer": True})
        wait_for(client, lambda s, i=prompt["id"]: (s["prompt"] or {}).get("id") != i)
    assert client.get("/api/history").json()["history"][-1]["result"] == "finished"
