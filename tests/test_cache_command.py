"""`taskseq cache`: what the cache of fits and outcomes holds, and deleting what no run has used."""

from __future__ import annotations

import os
import time

import pytest

from taskseq.cli import main
from taskseq.experiments.outcome_cache import OutcomeCache
from taskseq.learn.estimator import StepScorer
from taskseq.runtime import cache

DAY = 86400.0
KEY = "ab" + "0" * 62


@pytest.fixture(scope="module")
def steps(benchmark_steps):
    contexts, _ = benchmark_steps
    return contexts[:60]


@pytest.fixture
def root(tmp_path, monkeypatch):
    monkeypatch.setenv(cache.CACHE_ENV, str(tmp_path / "cache"))
    return tmp_path / "cache"


def _age(path, days):
    then = time.time() - days * DAY
    os.utime(path, (then, then))


def _fit(steps):
    return StepScorer("full", C=1.0).fit(steps)


def test_the_command_counts_what_a_fit_and_an_outcome_left(steps, root, capsys):
    _fit(steps)
    OutcomeCache(root / "outcomes").save(KEY, [{"scenario": "s1", "arg_correct": True}])
    assert main(["cache", str(root)]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert lines[0] == f"{root}:"
    fits, outcomes = lines[1].split(), lines[2].split()
    assert fits[:3] == ["fits", "1", "entries"] and outcomes[:3] == ["outcomes", "1", "entries"]
    assert fits[4] == "kB" and float(fits[3]) > 0 and outcomes[4] == "B" and int(outcomes[3]) > 0
    assert "never" not in lines[1] and "never" not in lines[2]


def test_a_read_marks_an_entry_used_so_pruning_keeps_it(steps, root, capsys):
    _fit(steps)
    (fit_entry,) = (root / "fits").rglob("*.npz")
    outcomes = OutcomeCache(root / "outcomes")
    outcomes.save(KEY, [1, 2])
    _age(fit_entry, 10)
    _age(outcomes.path(KEY), 10)
    assert _fit(steps).from_cache_  # read back: used now
    assert time.time() - fit_entry.stat().st_mtime < DAY
    assert main(["cache", str(root), "--unused-for", "5"]) == 0
    assert capsys.readouterr().out.startswith("deleted 1 files unused for 5 days")
    assert fit_entry.exists() and not outcomes.path(KEY).exists()
    assert not outcomes.path(KEY).parent.exists()  # its emptied two-character folder goes too
    assert _fit(steps).from_cache_  # the kept fit still reads back
    assert outcomes.load(KEY) is None


def test_clear_deletes_every_entry_and_only_old_leftovers_of_interrupted_writes(steps, root, capsys):
    _fit(steps)
    (fit_entry,) = (root / "fits").rglob("*.npz")
    old, young = (fit_entry.parent / f".{fit_entry.stem}.{tag}.npz" for tag in ("x1", "x2"))
    old.write_bytes(b"half")
    young.write_bytes(b"half")
    _age(old, 1)
    assert main(["cache", str(root), "--clear"]) == 0
    assert capsys.readouterr().out.startswith("deleted 2 files")
    assert not fit_entry.exists() and not old.exists()
    assert young.exists()  # younger than an hour: maybe a write under way
    assert not _fit(steps).from_cache_


def test_a_folder_that_is_not_a_cache_loses_nothing(steps, root, capsys):
    _fit(steps)
    (root / "notes.txt").write_text("mine\n")
    assert main(["cache", str(root), "--clear"]) == 2
    err = capsys.readouterr().err
    assert "not a cache folder" in err and "notes.txt" in err
    assert len(list((root / "fits").rglob("*.npz"))) == 1 and (root / "notes.txt").exists()


def test_a_missing_folder_is_named(tmp_path, capsys):
    assert main(["cache", str(tmp_path / "nowhere")]) == 2
    assert "nowhere: no such folder" in capsys.readouterr().err


@pytest.mark.parametrize("days", ["0", "-2", "abc", "inf", "nan"])
def test_days_that_are_not_a_positive_number_are_refused(days, tmp_path, capsys):
    with pytest.raises(SystemExit) as exit_:
        main(["cache", str(tmp_path), "--unused-for", days])
    assert exit_.value.code == 2
    assert f"expected a number of days above 0, got '{days}'" in capsys.readouterr().err


def test_unused_for_and_clear_are_one_or_the_other(tmp_path, capsys):
    with pytest.raises(SystemExit):
        main(["cache", str(tmp_path), "--clear", "--unused-for", "3"])
    assert "not allowed with argument" in capsys.readouterr().err


def test_a_kept_draw_of_rooms_is_counted_and_cleared_as_one_entry(root, capsys):
    from taskseq.features.drawn_rooms import StepsCache, drawn_room_steps
    from taskseq.settings import Procedural

    drawn_room_steps.cache_clear()
    drawn_room_steps(1, 3, Procedural())
    drawn_room_steps.cache_clear()
    (entry,) = (root / StepsCache.kind).glob("??/*.steps")
    leftover = entry.parent / f".{entry.name}.old.123"  # a replaced entry an interrupted run left
    leftover.mkdir()
    _age(leftover, 1)
    assert main(["cache", str(root)]) == 0
    line = capsys.readouterr().out.splitlines()[3].split()
    assert line[:3] == ["steps", "1", "entries"] and line[4] == "kB"
    assert main(["cache", str(root), "--clear"]) == 0
    assert capsys.readouterr().out.startswith("deleted 2 files")
    assert not entry.exists() and not leftover.exists()
