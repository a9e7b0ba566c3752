"""People's demonstrations on disk: one JSON Lines file per environment, each append whole or not at all.

An append takes an exclusive `flock` on the folder's lock file (so servers,
threads and the teaching script never interleave), writes the old content
plus the new line to a temporary file beside the log, syncs it, renames it
over the log and reads it back. A reader, or a server stopped at any moment,
sees the log before or after the record, never a part of it.
"""

from __future__ import annotations

import fcntl
import os
import secrets
import tempfile
import threading
from pathlib import Path
from typing import Any

from ..demonstrations.records import demonstration_record, dumps, parse_record, state_from_dict
from ..demonstrations.validate import LogError, LoggedRecord, check_record
from ..product import in_names
from ..runtime.atomic import as_opened
from ..sim.primitives import Action, execute
from ..sim.scenarios import Scenario
from ..sim.tasks import Task
from .environments import SAFE_NAME, Environment
from .rules import unsafe_reason

LOCK_NAME = ".lock"


class WriterClosed(RuntimeError):
    """The server is stopping: no new record is started."""


def person_record(env: Environment, task: Task, actions: list[Action], participant: str | None = None,
                  corrected: list[int] | None = None) -> dict[str, Any]:
    """The log record of a demonstration made in the browser; `corrected` only for a program made with the planner."""
    record = demonstration_record(Scenario(env.env_id, task, env.state, (tuple(actions),)), 0)
    # people may demonstrate one scenario many times: a random suffix keeps every demo_id unique
    record["demo_id"] = f"{record['scenario_id']}/{participant or 'person'}-{secrets.token_hex(6)}"
    if participant:
        record["participant"] = participant
    if corrected is not None:
        record["corrected"] = sorted(corrected)
    return record


def check_safe(item: LoggedRecord) -> None:
    """Raise `LogError` at the first step of a checked record that breaks a safety rule.

    Ingest accepts such a record (the simulator lets an unsafe step happen, and an evaluation counts it), but a
    person's record teaches the planner: the pages refuse an unsafe step, and this keeps one out of a log even
    from another writer of records (the teaching script)."""
    specs, _, actions = parse_record(item.record)
    state = state_from_dict(specs, item.record["steps"][0]["state"])
    for k, action in enumerate(actions):
        reason = unsafe_reason(state, action)
        if reason is not None:
            raise LogError(item.path, item.line, f"steps[{k}]", f"{in_names(action, state.specs)}: {reason}")
        state = execute(state, action)


class RecordWriter:
    """Appends checked records to `<folder>/<env_id>.jsonl`; never writes anywhere else."""

    def __init__(self, folder: Path) -> None:
        self.folder = Path(folder).resolve()
        self._busy = threading.Lock()
        self._closed = False

    def path_for(self, env_id: str) -> Path:
        if not SAFE_NAME.match(env_id):
            raise ValueError(f"environment id {env_id!r} cannot name a log file (letters, digits, _ and - only)")
        path = self.folder / f"{env_id}.jsonl"
        if path.parent != self.folder:  # SAFE_NAME already excludes it; kept as the guarantee this class gives
            raise ValueError(f"{env_id!r} would write outside {self.folder}")
        return path

    def append(self, record: dict[str, Any]) -> Path:
        """Check the record as `taskseq ingest` will (schema, references, replay, goal) and that no step breaks a
        safety rule, then append it."""
        path = self.path_for(record["env_id"])
        item = LoggedRecord(path, 0, record)
        check_record(item)
        check_safe(item)
        line = (dumps(record) + "\n").encode("utf-8")
        with self._busy:
            if self._closed:
                raise WriterClosed("the server is stopping; the demonstration was not recorded")
            self.folder.mkdir(parents=True, exist_ok=True)
            with open(self.folder / LOCK_NAME, "a") as lock:
                fcntl.flock(lock, fcntl.LOCK_EX)
                try:
                    self._replace(path, line)
                finally:
                    fcntl.flock(lock, fcntl.LOCK_UN)
        return path

    def _replace(self, path: Path, line: bytes) -> None:
        old = path.read_bytes() if path.exists() else b""
        if old and not old.endswith(b"\n"):
            raise ValueError(f"{path.name} does not end with a whole line; it was not written by this server")
        fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", dir=self.folder)
        try:
            with os.fdopen(fd, "wb") as fh:
                fh.write(old + line)
                fh.flush()
                os.fsync(fh.fileno())
            as_opened(Path(tmp), path, directory=False)  # the log's own permissions, not mkstemp's owner-only ones
            os.replace(tmp, path)
        except BaseException:
            Path(tmp).unlink(missing_ok=True)
            raise
        dir_fd = os.open(self.folder, os.O_RDONLY)
        try:
            os.fsync(dir_fd)  # the rename itself survives a crash
        finally:
            os.close(dir_fd)
        written = path.read_bytes()
        if written != old + line:
            raise OSError(f"{path.name}: read back {len(written)} bytes, expected {len(old) + len(line)}")

    def close(self) -> None:
        """Wait for the append under way, if any, and refuse new ones (the server is stopping)."""
        with self._busy:
            self._closed = True
