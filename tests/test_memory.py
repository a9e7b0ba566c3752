"""The memory policy (`taskseq.runtime.memory`): a freed large array stays in the process's heap, child
processes take the policy from the environment, a user's own setting wins, and every `taskseq` command
applies it. Each case runs in a fresh interpreter: glibc reads the environment once, at a process's start."""

from __future__ import annotations

import json
import os
import subprocess
import sys

import pytest

from taskseq import cli
from taskseq.runtime import memory

pytestmark = pytest.mark.skipif(memory._glibc() is None or not hasattr(memory._glibc(), "mallinfo2"),
                                reason="the policy is glibc's malloc; the probe reads mallinfo2 (glibc 2.33 or later)")

ARRAY = 64 * 2**20  # bytes: past glibc's largest threshold for serving a block by a mapping of its own

# allocate and free one large array, then read glibc's own accounting (mallinfo2, glibc >= 2.33)
PROBE = r"""
import ctypes, json, os, sys
import numpy as np
from taskseq.runtime import memory

applied = memory.keep_freed_memory() if sys.argv[1] == "apply" else None

class Mallinfo2(ctypes.Structure):
    _fields_ = [(name, ctypes.c_size_t) for name in (
        "arena", "ordblks", "smblks", "hblks", "hblkhd", "usmblks", "fsmblks", "uordblks", "fordblks", "keepcost")]

libc = ctypes.CDLL("libc.so.6")
libc.mallinfo2.restype = Mallinfo2
array = np.ones(int(sys.argv[2]) // 8)
mapped = libc.mallinfo2().hblkhd
del array
print(json.dumps({"applied": applied, "mapped_while_held": mapped, "free_in_heap": libc.mallinfo2().fordblks,
                  "environment": {name: os.environ.get(name) for name in memory.ENVIRONMENT}}))
"""


def probe(how: str, environment: dict[str, str]) -> dict:
    env = {k: v for k, v in os.environ.items() if k not in memory.ENVIRONMENT} | environment
    out = subprocess.run([sys.executable, "-c", PROBE, how, str(ARRAY)], env=env, capture_output=True, text=True,
                         check=True)
    return json.loads(out.stdout)


def test_without_the_policy_a_freed_large_array_goes_back_to_the_kernel():
    seen = probe("none", {})
    assert seen["mapped_while_held"] >= ARRAY  # served by a mapping of its own ...
    assert seen["free_in_heap"] < ARRAY  # ... and unmapped when freed


def test_the_policy_keeps_a_freed_large_array_in_the_heap():
    seen = probe("apply", {})
    assert seen["applied"] is True
    assert seen["mapped_while_held"] < ARRAY
    assert seen["free_in_heap"] >= ARRAY
    assert seen["environment"] == memory.ENVIRONMENT  # what the processes it starts read


def test_a_child_process_takes_the_policy_from_the_environment():
    seen = probe("none", memory.ENVIRONMENT)
    assert seen["mapped_while_held"] < ARRAY
    assert seen["free_in_heap"] >= ARRAY


def test_a_users_own_setting_is_kept():
    own = {"MALLOC_MMAP_MAX_": "65536"}
    seen = probe("apply", own)
    assert seen["applied"] is False
    assert seen["environment"] == {"MALLOC_MMAP_MAX_": "65536", "MALLOC_TRIM_THRESHOLD_": None}
    assert seen["mapped_while_held"] >= ARRAY  # glibc's own behaviour, as the user asked


def test_every_command_applies_the_policy(monkeypatch, tmp_path):
    calls = []
    monkeypatch.setattr(memory, "keep_freed_memory", lambda: calls.append(True))
    assert cli.main(["--no-mlflow", "generate", "--world-seed", "0", "--output", str(tmp_path / "raw")]) == 0
    assert calls == [True]
