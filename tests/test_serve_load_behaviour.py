"""serve/load.py without a server: the summary of hand-made latencies, the step form, the client's address, the
scripted tasks, and the command line (its load run replaced by a spy)."""

from __future__ import annotations

import re
import threading
import time
import urllib.parse
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer

import pytest

from taskseq.serve import load
from taskseq.serve.environments import world_environment
from taskseq.serve.load import Client, LoadResult, _step, scripted_tasks
from taskseq.sim.primitives import Action
from taskseq.sim.scenarios import doable_tasks
from taskseq.sim.tasks import Task


def test_the_summary_gives_counts_median_95th_percentile_and_max_in_milliseconds():
    result = LoadResult(latencies=[0.001 * i for i in range(1, 21)], saved=["a", "b"], errors=["x"])
    # 20 requests: the median of 1..20 ms is 10.5; the 95th percentile is the 20 * 0.95 = 19th sorted (index 19: 20)
    assert result.requests == 20
    assert result.summary() == ("20 requests, 2 demonstrations saved, 1 errors; response time median 10.5 ms, "
                                "95th percentile 20.0 ms, max 20.0 ms")
    assert LoadResult(latencies=[0.1, 0.3, 0.2]).summary().endswith(
        "median 200.0 ms, 95th percentile 300.0 ms, max 300.0 ms")  # seconds to milliseconds
    one = LoadResult(latencies=[0.0042])
    assert one.summary() == ("1 requests, 0 demonstrations saved, 0 errors; response time median 4.2 ms, "
                             "95th percentile 4.2 ms, max 4.2 ms")
    unsorted = LoadResult(latencies=[0.009, 0.001, 0.005, 0.003] + [0.002] * 16)
    # sorted: 1, 2 x 16, 3, 5, 9: median 2, index int(0.95 * 20) = 19 is the 9, max 9
    assert unsorted.summary().endswith("median 2.0 ms, 95th percentile 9.0 ms, max 9.0 ms")
    forty = LoadResult(latencies=[0.001 * i for i in range(40, 0, -1)])
    assert "95th percentile 39.0 ms, max 40.0 ms" in forty.summary()  # index int(0.95 * 40) = 38


def test_a_step_form_has_both_arguments_empty_when_missing():
    assert _step(3, Action("done")) == {"n": "3", "primitive": "done", "a1": "", "a2": ""}
    assert _step(0, Action("grasp", ("obj2",))) == {"n": "0", "primitive": "grasp", "a1": "obj2", "a2": ""}
    assert _step(7, Action("hold_above", ("a", "b"))) == {"n": "7", "primitive": "hold_above", "a1": "a", "a2": "b"}


def test_a_client_talks_to_the_urls_host_and_port_with_defaults():
    result, lock = LoadResult(), threading.Lock()
    c = Client("http://example.org:8123/x", result, lock)
    assert (c.host, c.port, c.cookie) == ("example.org", 8123, None)
    assert c.result is result and c.lock is lock
    d = Client("http://example.org", result, lock)
    assert (d.host, d.port) == ("example.org", 80)
    e = Client("", result, lock)
    assert (e.host, e.port) == ("127.0.0.1", 80)


def test_the_scripted_tasks_are_the_first_doable_ones_with_their_demonstrations():
    tasks = scripted_tasks(0, "env02", 3)
    expected = doable_tasks(world_environment(0, "env02").state, limit=3)
    assert len(tasks) == 3 and tasks == expected
    assert scripted_tasks(1, "env02", 2)[0][0] == doable_tasks(world_environment(1, "env02").state, limit=1)[0][0]


def test_the_command_line_runs_the_load_it_is_given_and_prints_the_summary(monkeypatch, capsys):
    calls = []

    def run_load(url, clients, rounds):
        calls.append((url, clients, rounds))
        return LoadResult(latencies=[0.002], saved=["s"])

    monkeypatch.setattr(load, "run_load", run_load)
    monkeypatch.setattr("sys.argv", ["load", "--url", "http://h:1", "--clients", "5", "--rounds", "2"])
    load.main()
    monkeypatch.setattr("sys.argv", ["load"])
    load.main()
    assert calls == [("http://h:1", 5, 2), ("http://127.0.0.1:8765", 4, 6)]
    assert capsys.readouterr().out == 2 * ("1 requests, 1 demonstrations saved, 0 errors; response time median "
                                           "2.0 ms, 95th percentile 2.0 ms, max 2.0 ms\n")


def test_the_command_line_explains_its_options(monkeypatch, capsys):
    monkeypatch.setattr("sys.argv", ["load", "--help"])
    with pytest.raises(SystemExit):
        load.main()
    out = capsys.readouterr().out
    assert "A bounded load on a running `taskseq serve`" in out and "Each client is one browser" not in out
    for option, text in (("--url URL", "the running server"), ("--clients CLIENTS", "browsers at once"),
                         ("--rounds ROUNDS", "demonstrations per browser")):
        assert re.search(rf"{option}\s+{text}\n", out), option


# --- against a scripted server that records every request ------------------------------------------------------------

class Recorder:
    """A stand-in for `taskseq serve`: each request recorded with its raw header names, each browser given a cookie
    on its first request, and the status `status_for` chooses."""

    def __init__(self, status_for=None, finished='<p id="demo-id">a&amp;b</p>'):
        self.requests, self.lock, self.sessions = [], threading.Lock(), 0
        self.status_for = status_for or (lambda method, path, form: 200)
        recorder = self

        class Handler(BaseHTTPRequestHandler):
            def log_message(self, *args):
                pass

            def _answer(self):
                n = int(self.headers.get("Content-Length") or 0)
                body = self.rfile.read(n).decode() if n else None
                form = dict(urllib.parse.parse_qsl(body)) if body else None
                with recorder.lock:
                    status = recorder.status_for(self.command, self.path, form)
                    cookie = self.headers.get("Cookie")
                    if cookie is None:
                        recorder.sessions += 1
                    recorder.requests.append(SimpleRequest(self.command, self.path, list(self.headers.items()),
                                                           body, form, cookie or f"sid=s{recorder.sessions}"))
                text = finished if self.path == "/finished" else "page"
                self.send_response(status)
                if cookie is None:
                    self.send_header("Set-Cookie", f"sid=s{recorder.sessions}; Path=/; HttpOnly")
                self.send_header("Content-Length", str(len(text.encode())))
                self.end_headers()
                self.wfile.write(text.encode())

            do_GET = do_POST = _answer

        self.server = ThreadingHTTPServer(("127.0.0.1", 0), Handler)
        self.url = f"http://127.0.0.1:{self.server.server_port}"
        self.thread = threading.Thread(target=self.server.serve_forever)
        self.thread.start()

    def close(self):
        self.server.shutdown()
        self.server.server_close()
        self.thread.join()


class SimpleRequest:
    def __init__(self, method, path, headers, body, form, browser):
        self.method, self.path, self.headers, self.body, self.form = method, path, headers, body, form
        self.cookie = dict(headers).get("Cookie")
        self.browser = browser  # the cookie it sent, or the one it was given

    def names(self):
        return [k for k, _ in self.headers]


@pytest.fixture
def recorder():
    made = []

    def make(**kwargs):
        made.append(Recorder(**kwargs))
        return made[-1]

    yield make
    for r in made:
        r.close()


def test_a_request_sends_its_form_its_cookie_and_times_itself(recorder):
    server = recorder()
    result = LoadResult()
    client = Client(server.url, result, threading.Lock())
    start = time.perf_counter()
    assert client.request("GET", "/") == "page"
    client.request("POST", "/task", {"task": "stir", "arg1": "a b"}, 200)
    client.request("POST", "/step", {}, 200)
    took = time.perf_counter() - start
    get, post, empty = server.requests
    assert (get.method, get.path, get.body, get.cookie) == ("GET", "/", None, None)
    assert "Content-Type" not in get.names() and "Content-Length" not in get.names()  # a GET has no body
    assert client.cookie == "sid=s1"  # the cookie without its attributes
    assert (post.method, post.path, post.body, post.cookie) == ("POST", "/task", "task=stir&arg1=a+b", "sid=s1")
    assert ("Content-Type", "application/x-www-form-urlencoded") in post.headers and "Cookie" in post.names()
    assert (empty.body, ("Content-Type", "application/x-www-form-urlencoded") in empty.headers) == (None, True)
    assert result.errors == [] and len(result.latencies) == 3
    assert all(isinstance(t, float) and 0 < t <= took for t in result.latencies)
    assert sum(result.latencies) <= took


def test_a_status_other_than_the_expected_one_is_an_error_naming_the_request(recorder):
    server = recorder(status_for=lambda method, path, form: 409 if path == "/step" else 200)
    result = LoadResult()
    client = Client(server.url, result, threading.Lock())
    client.request("POST", "/step", {"n": "0"}, 303)
    client.request("POST", "/step", {"n": "0"}, 409)
    client.request("GET", "/x", expect=303)
    assert result.errors == ["POST /step: status 409, expected 303", "GET /x: status 200, expected 303"]
    assert len(result.latencies) == 3


DEMO = [Action("move_close", ("obj20",)), Action("grasp", ("obj20",)), Action("release", ("obj20",))]


def flow_status(method, path, form):
    """What `taskseq serve` answers a scripted person: redirects after posts, 409 for the step taken too early."""
    if method == "POST" and path == "/step" and form["n"] == "0" and form["primitive"] == "grasp":
        return 409
    return 303 if method == "POST" else 200


def test_a_scripted_person_chooses_tries_a_refused_step_demonstrates_and_finishes(recorder):
    server = recorder(status_for=flow_status)
    result = LoadResult()
    Client(server.url, result, threading.Lock()).demonstrate(4, "env03", Task("pour_to", ("obj27", "obj14")), DEMO)
    seen = [(r.method, r.path, r.form) for r in server.requests]
    step = [{"n": "0", "primitive": "grasp", "a1": "obj20"}]  # urlencoded empty fields are dropped by parse_qsl
    assert seen == [
        ("POST", "/environment", {"source": "world", "seed": "4", "env_id": "env03"}),
        ("POST", "/task", {"task": "pour_to", "arg1": "obj27", "arg2": "obj14", "mode": "demonstrate"}),
        ("GET", "/demonstrate", None),
        ("POST", "/step", step[0]),
        ("POST", "/step", {"n": "0", "primitive": "move_close", "a1": "obj20"}), ("GET", "/demonstrate", None),
        ("POST", "/step", {"n": "1", "primitive": "grasp", "a1": "obj20"}), ("GET", "/demonstrate", None),
        ("POST", "/step", {"n": "2", "primitive": "release", "a1": "obj20"}), ("GET", "/demonstrate", None),
        ("POST", "/step", {"n": "3", "primitive": "done"}),
        ("GET", "/finished", None)]
    assert len({r.cookie for r in server.requests[1:]}) == 1  # one browser
    assert result.errors == [] and result.saved == ["a&b"] and len(result.latencies) == len(seen)


def redirect_posts(method, path, form):
    return 303 if method == "POST" else 200


def test_a_demonstration_that_does_not_start_by_driving_close_tries_no_refused_step(recorder):
    server = recorder(status_for=redirect_posts)
    result = LoadResult()
    Client(server.url, result, threading.Lock()).demonstrate(0, "env01", Task("stir", ("obj3",)), DEMO[1:])
    assert [r.form["n"] for r in server.requests if r.path == "/step"] == ["0", "1", "2"]
    assert server.requests[1].form == {"task": "stir", "arg1": "obj3", "mode": "demonstrate"}
    assert result.errors == []


def test_a_finished_page_without_a_saved_demonstration_is_an_error(recorder):
    server = recorder(status_for=redirect_posts, finished="<p>nothing</p>")
    result = LoadResult()
    Client(server.url, result, threading.Lock()).demonstrate(0, "env01", Task("stir", ("obj3",)), DEMO[1:])
    assert result.saved == [] and result.errors == ["stir(obj3): the finished page names no saved demonstration"]


def test_a_load_gives_each_browser_its_tasks_in_turn_over_the_environments(recorder):
    server = recorder(status_for=flow_status)
    envs = ("env01", "env02", "env03")
    result = load.run_load(server.url, clients=2, rounds=4, seed=0, env_ids=envs)
    plans = {e: scripted_tasks(0, e, 8) for e in envs}
    by_browser = {}
    for r in server.requests:
        if r.path in ("/environment", "/task"):
            by_browser.setdefault(r.browser, []).append(r.form)
    assert sorted(by_browser) == ["sid=s1", "sid=s2"]
    got = sorted([(forms[j]["env_id"], forms[j + 1]["task"], forms[j + 1]["arg1"]) for j in range(0, 8, 2)]
                 for forms in by_browser.values())
    expected = sorted([(envs[(i + r) % 3], plans[envs[(i + r) % 3]][i * 4 + r][0].name,
                        plans[envs[(i + r) % 3]][i * 4 + r][0].args[0]) for r in range(4)] for i in range(2))
    assert got == expected
    assert len(result.saved) == 8 and result.errors == []


def test_a_load_on_no_server_records_each_browsers_connection_error(recorder):
    server = recorder()
    url = server.url
    server.close()
    server.close = lambda: None
    result = load.run_load(url, clients=2, rounds=1, seed=0, env_ids=("env01",))
    first, second = scripted_tasks(0, "env01", 2)  # browser i demonstrates task i
    assert sorted(e.split(": ", 1)[0] for e in result.errors) == sorted([str(first[0]), str(second[0])])
    assert all("refused" in e.lower() for e in result.errors)
