"""The fit cache: a fit read back is the fit done, and anything that decides a fit misses it."""

from __future__ import annotations

import json
import subprocess
import sys
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from taskseq.features.context import candidate_index
from taskseq.learn import fit_cache
from taskseq.learn.estimator import StepScorer
from taskseq.runtime import cache, sources


@pytest.fixture
def cache_dir(tmp_path, monkeypatch):
    monkeypatch.setenv(cache.CACHE_ENV, str(tmp_path / "cache"))
    return tmp_path / "cache" / "fits"


@pytest.fixture(scope="module")
def steps(benchmark_steps):
    contexts, _ = benchmark_steps
    return contexts[:120]


def _entries(folder):
    return sorted(folder.rglob("*.npz"))


def _same_fit(a: StepScorer, b: StepScorer, same_times: bool = True) -> None:
    assert a.w_.tobytes() == b.w_.tobytes()
    if same_times:  # read back: the record of the fit that stored it, its times included
        assert a.ssvm_.history_ == b.ssvm_.history_ and a.fit_seconds_ == b.fit_seconds_
    else:
        assert [replace(it, seconds=0) for it in a.ssvm_.history_] == [replace(it, seconds=0)
                                                                       for it in b.ssvm_.history_]
    assert a.ssvm_.primal_objective_ == b.ssvm_.primal_objective_
    assert a.ssvm_.dual_objective_ == b.ssvm_.dual_objective_
    assert a.ssvm_.n_iter_ == b.ssvm_.n_iter_ and a.n_steps_ == b.n_steps_
    ca, cb = a.ssvm_.cuts_, b.ssvm_.cuts_
    assert (ca.deltas != cb.deltas).nnz == 0 and ca.deltas.shape == cb.deltas.shape
    for x, y in ((ca.losses, cb.losses), (ca.examples, cb.examples), (ca.alpha, cb.alpha)):
        assert x.tobytes() == y.tobytes() and x.dtype == y.dtype
    assert (ca.C, ca.n_examples, ca.fingerprint) == (cb.C, cb.n_examples, cb.fingerprint)


def test_a_fit_read_back_is_the_fit_done_and_starts_its_neighbours_alike(steps, cache_dir, monkeypatch):
    from taskseq.runtime.atomic import WRITTEN

    before = len(WRITTEN)
    done = StepScorer("full", C=1.0).fit(steps)
    assert not done.from_cache_ and len(_entries(cache_dir)) == 1
    assert len(WRITTEN) == before  # an entry is no output of the command: "N files already replaced" omits it
    read = StepScorer("full", C=1.0).fit(steps)
    assert read.from_cache_
    _same_fit(done, read)
    assert read.predict(steps) == done.predict(steps)
    # a neighbour warm-started from the fit read back is the one started from the fit done, bit for bit
    monkeypatch.delenv(cache.CACHE_ENV)
    from_done = StepScorer("full", C=3.0).fit(steps, warm_start=done)
    from_read = StepScorer("full", C=3.0).fit(steps, warm_start=read)
    assert not from_read.from_cache_
    _same_fit(from_done, from_read, same_times=False)


def test_whatever_decides_a_fit_misses_the_cache(steps, cache_dir):
    StepScorer("full", C=1.0).fit(steps)
    base = StepScorer("full", C=1.0).fit(steps[:60])  # other steps
    assert not base.from_cache_
    assert not StepScorer("full", C=3.0).fit(steps).from_cache_  # another setting
    assert not StepScorer("relations", C=1.0).fit(steps).from_cache_  # other features
    labels = [x.gold for x in steps]
    p, a1, a2 = candidate_index(steps[0].n)
    labels[0] = next(y for y in zip(p.tolist(), a1.tolist(), a2.tolist(), strict=True) if y != tuple(steps[0].gold))
    assert not StepScorer("full", C=1.0).fit(steps, y=labels).from_cache_  # other labels
    assert not StepScorer("full", C=1.0).fit(steps, warm_start=base).from_cache_  # another start
    assert StepScorer("full", C=1.0).fit(steps, warm_start=base).from_cache_
    assert StepScorer("full", C=1.0).fit(steps).from_cache_


def test_a_change_to_the_learner_code_misses_and_one_elsewhere_does_not(steps, cache_dir, monkeypatch):
    StepScorer("full", C=1.0).fit(steps)
    learner_files = sources.import_closure("taskseq.learn.estimator")
    names = {p.relative_to(sources.ROOT).as_posix() for p in learner_files}
    assert {"taskseq/learn/ssvm.py", "taskseq/learn/working_set.py", "taskseq/learn/mrf.py",
            "taskseq/features/context.py"} <= names
    assert not any(n.startswith(("taskseq/plan/", "taskseq/methods/", "taskseq/report/")) for n in names)
    real = sources.code_fingerprint
    monkeypatch.setattr(fit_cache, "code_fingerprint", lambda module: real(module) + "changed")
    fit_cache._environment.cache_clear()  # read once per process: as a new process after the change would
    try:
        assert not StepScorer("full", C=1.0).fit(steps).from_cache_
    finally:
        monkeypatch.setattr(fit_cache, "code_fingerprint", real)
        fit_cache._environment.cache_clear()
    assert StepScorer("full", C=1.0).fit(steps).from_cache_


def test_an_unreadable_entry_is_fitted_again_and_replaced(steps, cache_dir):
    done = StepScorer("full", C=1.0).fit(steps)
    (entry,) = _entries(cache_dir)
    entry.write_bytes(b"not a zip file")
    with pytest.warns(UserWarning, match="unreadable entry of the cache is fitted again"):
        again = StepScorer("full", C=1.0).fit(steps)
    assert not again.from_cache_ and again.w_.tobytes() == done.w_.tobytes()
    assert StepScorer("full", C=1.0).fit(steps).from_cache_
    # a whole archive with a record that misses a field is no fit either
    np.savez(entry, w=done.w_, meta=np.array(json.dumps({"format": fit_cache.FORMAT, "history": []})))
    with pytest.warns(UserWarning, match="unreadable entry of the cache is fitted again"):
        assert not StepScorer("full", C=1.0).fit(steps).from_cache_


def test_a_variable_naming_a_file_is_refused_before_any_fit(steps, tmp_path, monkeypatch):
    (tmp_path / "cache").write_text("")
    monkeypatch.setenv(cache.CACHE_ENV, str(tmp_path / "cache"))
    with pytest.raises(ValueError, match="TASKSEQ_CACHE=.*: not a folder"):
        StepScorer("full", C=1.0).fit(steps)


def test_without_the_variable_nothing_is_written(steps, tmp_path, monkeypatch):
    monkeypatch.delenv(cache.CACHE_ENV, raising=False)
    monkeypatch.chdir(tmp_path)
    assert fit_cache.FitCache.active() is None
    StepScorer("full", C=1.0).fit(steps)
    assert list(tmp_path.iterdir()) == []


def test_a_steps_digest_is_kept_for_that_step_only(steps):
    from dataclasses import replace as changed

    x = steps[0]
    assert fit_cache.step_digest(x) == fit_cache.step_digest(x)
    other = changed(x, objects=x.objects + 1.0)  # another object: its own digest, though its id may be x's old one
    assert fit_cache.step_digest(other) != fit_cache.step_digest(x)
    assert fit_cache.step_digest(changed(x)) == fit_cache.step_digest(x)  # equal content, equal digest
    with_relations = [changed(x, relations=np.full((x.n, 3), v)) for v in (0.0, 1.0)]
    assert fit_cache.step_digest(with_relations[0]) != fit_cache.step_digest(with_relations[1])
    # a step made where a hashed one was freed may take its id: it gets its own digest, not the freed one's
    gone = changed(x, objects=x.objects + 2.0)
    freed_digest, freed_id = fit_cache.step_digest(gone), id(gone)
    del gone
    later = [changed(x, objects=x.objects + 3.0 + k) for k in range(50)]
    reused = [y for y in later if id(y) == freed_id]
    assert reused, "CPython gave the freed step's id to none of 50 new ones: the case is not exercised"
    got = fit_cache.step_digest(reused[0])
    fit_cache._DIGESTS.clear()
    assert got == fit_cache.step_digest(reused[0]) != freed_digest


def test_the_closure_follows_relative_imports_and_packages(tmp_path):
    closure = {p.relative_to(sources.ROOT).as_posix() for p in sources.import_closure("taskseq.learn.store")}
    # store imports estimator (relative), which imports the features (two dots up) and their package
    assert {"taskseq/__init__.py", "taskseq/learn/__init__.py", "taskseq/learn/estimator.py",
            "taskseq/learn/fit_cache.py", "taskseq/features/__init__.py", "taskseq/runtime/sources.py"} <= closure
    with pytest.raises(ValueError, match="no such module"):
        sources.import_closure("taskseq.no_such_module")
    assert np.all([p.is_file() for p in sources.import_closure("taskseq.learn.store")])


def test_a_benchmark_fits_afresh_whatever_the_variable_says(steps, cache_dir):
    StepScorer("full", C=1.0).fit(steps)
    with cache.disabled():
        assert fit_cache.FitCache.active() is None
        assert not StepScorer("full", C=1.0).fit(steps).from_cache_
    assert StepScorer("full", C=1.0).fit(steps).from_cache_  # the variable as it was afterwards
    assert len(_entries(cache_dir)) == 1


def test_the_closure_read_from_the_code_holds_every_module_an_import_loads():
    """The fingerprint reads imports from the text; a fresh interpreter's own account must not name more."""
    script = ("import sys, taskseq.learn.estimator\n"
              "print('\\n'.join(m.__file__ for n, m in sys.modules.items() if n.split('.')[0] == 'taskseq'))")
    loaded = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, check=True).stdout.split()
    assert loaded and {Path(f).resolve() for f in loaded} <= set(sources.import_closure("taskseq.learn.estimator"))
