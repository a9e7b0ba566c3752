"""The learned weights are the same bytes on every x86-64 processor.

A fresh clone on another machine must end `dvc repro` with `git status`
clean, so nothing between the demonstration logs and the stored weights may
depend on which instructions the processor offers. Three libraries choose
their code by the processor at run time, and each can be told to choose as on
an older or another one: NumPy's SIMD dispatch (`NPY_DISABLE_CPU_FEATURES`),
OpenBLAS's kernels (`OPENBLAS_CORETYPE`) and glibc's FMA variants of `log`
and friends (`GLIBC_TUNABLES`); Numba compiles for the host unless told a
generic processor (`NUMBA_CPU_NAME`). The test builds the features of the
first demonstrations and fits both feature sets on them in a fresh process
under each setting, and compares the bytes of the features, the score tables
at the learned weights, the objectives of every iteration and the weights.
Before the fixes (docs/pipeline.md, "Across processors") the relation
features (`np.log10`) changed with NumPy's dispatch, and the score tables and
objectives (BLAS products) with OpenBLAS's core type, from five training
steps on.

Run as a script (`python tests/test_processor_independence.py LOGS RECORDS`)
it prints those hashes for the processor it finds: the fit the test runs.
"""

from __future__ import annotations

import hashlib
import json
import os
import subprocess
import sys
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import numpy as np

RECORDS = 2  # demonstrations fitted on: a dozen steps, enough for the relation features to differ before the fix
# NumPy's dispatch targets above its x86-64 baseline, by the names NumPy 2.4 gives them
NUMPY_TARGETS = ("X86_V3", "X86_V4", "AVX512_ICL", "AVX512_SPR")


def _has_avx512() -> bool:
    try:
        return " avx512f " in Path("/proc/cpuinfo").read_text()
    except OSError:
        return False


def environments() -> dict[str, dict[str, str]]:
    """Settings that make the libraries run as on other x86-64 processors, by name."""
    envs = {
        "as found": {},
        "NumPy without AVX-512": {"NPY_DISABLE_CPU_FEATURES": " ".join(NUMPY_TARGETS[1:])},
        "NumPy at its baseline (no AVX2, no FMA)": {"NPY_DISABLE_CPU_FEATURES": " ".join(NUMPY_TARGETS)},
        "Numba for a generic x86-64": {"NUMBA_CPU_NAME": "generic"},
        "OpenBLAS as on Sandy Bridge (AVX, no FMA)": {"OPENBLAS_CORETYPE": "Sandybridge"},
        "OpenBLAS as on Prescott (SSE3)": {"OPENBLAS_CORETYPE": "Prescott"},
        "glibc without FMA and AVX2": {"GLIBC_TUNABLES": "glibc.cpu.hwcaps=-AVX2,-FMA,-FMA4"},
    }
    if _has_avx512():  # forcing AVX-512 kernels elsewhere would stop at the first instruction
        envs["OpenBLAS as on Skylake-X (AVX-512)"] = {"OPENBLAS_CORETYPE": "SkylakeX"}
    return envs


def _run(logs: Path, settings: dict[str, str]) -> dict:
    env = {**os.environ, **settings}
    done = subprocess.run([sys.executable, __file__, str(logs), str(RECORDS)], env=env, capture_output=True, text=True)
    assert done.returncode == 0, f"{settings}: {done.stderr[-2000:]}"
    return json.loads(done.stdout.splitlines()[-1])


def test_same_bytes_under_every_processor_setting(benchmark_logs: Path) -> None:
    envs = environments()
    with ThreadPoolExecutor(max_workers=2) as pool:
        results = dict(zip(envs, pool.map(lambda s: _run(benchmark_logs, s), envs.values()), strict=True))
    # a NumPy that renamed its targets would ignore the setting silently: the names must be its own
    assert set(NUMPY_TARGETS) <= set(results["as found"]["numpy_targets"]), results["as found"]["numpy_targets"]
    reference = results["as found"]["hashes"]
    differing = {name: sorted(k for k, v in r["hashes"].items() if v != reference[k])
                 for name, r in results.items()}
    assert not any(differing.values()), f"bytes differ from the processor as found: {differing}"


def _digest(arrays: list[np.ndarray]) -> str:
    h = hashlib.sha256()
    for a in arrays:
        h.update(np.ascontiguousarray(a).tobytes())
    return h.hexdigest()


def _fit_hashes(logs: Path, records: int) -> dict:
    """Features, score tables, objectives and weights of both feature sets, fitted on the first `records` demos."""
    from numpy._core._multiarray_umath import __cpu_dispatch__

    from taskseq.demonstrations.ingest import load_logs
    from taskseq.features.dataset import build_steps
    from taskseq.learn.estimator import StepScorer
    from taskseq.learn.mrf import StepBatch

    _, tables = load_logs(logs)
    steps, _ = build_steps([item.record for item in tables[:records]])
    hashes = {"features": _digest([a for x in steps for a in (x.objects, x.task_rel, x.relations)])}
    for features in ("full", "relations"):
        planner = StepScorer(features, C=3.0, tol=1e-3).fit(steps)
        f = planner.model_.batch_tables(StepBatch.of(steps, features == "relations"), planner.w_)
        hashes[f"{features} tables"] = _digest([f.P, f.U1, f.U2, f.pair, f.left, f.right])
        hashes[f"{features} objectives"] = _digest([np.array([[i.primal, i.dual] for i in planner.ssvm_.history_])])
        hashes[f"{features} weights"] = _digest([planner.w_])
    return {"hashes": hashes, "numpy_targets": list(__cpu_dispatch__), "steps": len(steps)}


if __name__ == "__main__":
    print(json.dumps(_fit_hashes(Path(sys.argv[1]), int(sys.argv[2]))))
