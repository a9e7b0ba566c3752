"""A bounded load on a running `taskseq serve`: scripted people demonstrating tasks at once, timed per request.

Each client is one browser (its own session cookie): it chooses a benchmark
environment, tries an infeasible first step (refused), takes the scripted
demonstrator's steps, reloading the page after each, and ends with `done`.
Used by the tests (no record lost, no partial file) and by hand to measure
the page's response time:

    python -m taskseq.serve.load --url http://127.0.0.1:8765 --clients 4 --rounds 6
"""

from __future__ import annotations

import argparse
import html
import http.client
import re
import statistics
import threading
import time
import urllib.parse
from dataclasses import dataclass, field

from ..sim.primitives import Action
from ..sim.scenarios import doable_tasks
from ..sim.tasks import Task
from .environments import world_environment

SAVED = re.compile(r'id="demo-id">([^<]*)<')


@dataclass
class LoadResult:
    latencies: list[float] = field(default_factory=list)  # seconds per request
    saved: list[str] = field(default_factory=list)  # demo ids the server said it saved (from /finished)
    errors: list[str] = field(default_factory=list)

    @property
    def requests(self) -> int:
        return len(self.latencies)

    def summary(self) -> str:
        ms = sorted(1000 * t for t in self.latencies)
        p95 = ms[min(len(ms) - 1, int(0.95 * len(ms)))]
        return (f"{self.requests} requests, {len(self.saved)} demonstrations saved, {len(self.errors)} errors; "
                f"response time median {statistics.median(ms):.1f} ms, 95th percentile {p95:.1f} ms, "
                f"max {ms[-1]:.1f} ms")


def scripted_tasks(seed: int, env_id: str, n: int) -> list[tuple[Task, list[Action]]]:
    """The first `n` tasks of the environment the scripted demonstrator can do, with its first sequence."""
    return doable_tasks(world_environment(seed, env_id).state, limit=n)


class Client:
    """One browser: a cookie, and every request timed and checked for the status it should get."""

    def __init__(self, url: str, result: LoadResult, lock: threading.Lock) -> None:
        parts = urllib.parse.urlsplit(url)
        self.host, self.port = parts.hostname or "127.0.0.1", parts.port or 80
        self.cookie: str | None = None
        self.result, self.lock = result, lock

    def request(self, method: str, path: str, form: dict[str, str] | None = None, expect: int = 200) -> str:
        body = urllib.parse.urlencode(form or {})
        headers = {"Content-Type": "application/x-www-form-urlencoded"} if form is not None else {}
        if self.cookie:
            headers["Cookie"] = self.cookie
        conn = http.client.HTTPConnection(self.host, self.port)
        start = time.perf_counter()
        try:
            conn.request(method, path, body=body if form is not None else None, headers=headers)
            resp = conn.getresponse()
            text = resp.read().decode("utf-8")
        finally:
            conn.close()
        elapsed = time.perf_counter() - start
        cookie = resp.getheader("Set-Cookie")
        if cookie:
            self.cookie = cookie.split(";", 1)[0]
        with self.lock:
            self.result.latencies.append(elapsed)
            if resp.status != expect:
                self.result.errors.append(f"{method} {path}: status {resp.status}, expected {expect}")
        return text

    def demonstrate(self, seed: int, env_id: str, task: Task, actions: list[Action]) -> None:
        self.request("POST", "/environment", {"source": "world", "seed": str(seed), "env_id": env_id}, 303)
        args = {"arg1": task.args[0], "arg2": task.args[1] if len(task.args) > 1 else ""}
        self.request("POST", "/task", {"task": task.name, **args, "mode": "demonstrate"}, 303)
        self.request("GET", "/demonstrate")
        far = actions[1] if actions[0].primitive == "move_close" else None  # grasp before driving close: refused
        if far is not None:
            self.request("POST", "/step", _step(0, far), 409)
        for k, action in enumerate(actions):
            self.request("POST", "/step", _step(k, action), 303)
            self.request("GET", "/demonstrate")
        self.request("POST", "/step", _step(len(actions), Action("done")), 303)
        saved = SAVED.search(self.request("GET", "/finished"))
        with self.lock:
            if saved:
                self.result.saved.append(html.unescape(saved.group(1)))
            else:
                self.result.errors.append(f"{task}: the finished page names no saved demonstration")


def _step(n: int, action: Action) -> dict[str, str]:
    args = list(action.args) + [""] * (2 - len(action.args))
    return {"n": str(n), "primitive": action.primitive, "a1": args[0], "a2": args[1]}


def run_load(url: str, clients: int, rounds: int, seed: int = 0,
             env_ids: tuple[str, ...] = ("env01", "env02")) -> LoadResult:
    """`clients` browsers at once, each demonstrating `rounds` tasks, alternating over `env_ids`."""
    plans = {e: scripted_tasks(seed, e, clients * rounds) for e in env_ids}
    result, lock = LoadResult(), threading.Lock()

    def work(i: int) -> None:
        client = Client(url, result, lock)
        for r in range(rounds):
            env = env_ids[(i + r) % len(env_ids)]
            task, actions = plans[env][(i * rounds + r) % len(plans[env])]
            try:
                client.demonstrate(seed, env, task, actions)
            except OSError as err:
                with lock:
                    result.errors.append(f"{task}: {err}")

    threads = [threading.Thread(target=work, args=(i,)) for i in range(clients)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    return result


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--url", default="http://127.0.0.1:8765", help="the running server")
    parser.add_argument("--clients", type=int, default=4, help="browsers at once")
    parser.add_argument("--rounds", type=int, default=6, help="demonstrations per browser")
    args = parser.parse_args()
    print(run_load(args.url, args.clients, args.rounds).summary())


if __name__ == "__main__":
    main()
