"""runtime/atomic.py and the command line on output paths given by hand: an output folder is replaced only when
that deletes nothing but a previous output of the same command, a path of the wrong kind (a file for a folder, a
folder for a file, a file in the way of a folder) is refused in one line naming it, and no temporary file or
folder is left behind, whatever is refused or fails."""

from __future__ import annotations

import argparse
import os
import re
from pathlib import Path

import numpy as np
import pytest

from taskseq.runtime import atomic
from taskseq.runtime.atomic import atomic_directory, atomic_file, write_arrays, write_text_atomic

WORKSHOP = Path(__file__).resolve().parents[1] / "docs" / "examples" / "workshop.yaml"


def tree(folder: Path) -> dict[str, str | None]:
    """Every path under `folder` (hidden ones too), with its text for a file: what a refusal must leave alone."""
    return {str(p.relative_to(folder)): (p.read_text() if p.is_file() else None) for p in sorted(folder.rglob("*"))}


def a_folder_with_other_files(folder: Path) -> dict[str, str | None]:
    """`folder` holding a previous output (`steps.csv`) and what a user keeps beside it."""
    (folder / "sub").mkdir(parents=True)
    (folder / "steps.csv").write_text("old output\n")
    (folder / "precious.txt").write_text("a week of notes\n")
    (folder / "sub" / "results.json").write_text("{}\n")
    return tree(folder)


# --- a folder replaced whole -----------------------------------------------------------------------------------------

def test_a_folder_holding_files_the_output_does_not_is_refused_and_left_as_it_was(tmp_path):
    target = tmp_path / "out"
    before_tree, before_written = a_folder_with_other_files(target), len(atomic.WRITTEN)
    with pytest.raises(ValueError) as refused, atomic_directory(target) as tmp:
        (tmp / "steps.csv").write_text("new output\n")
    message = str(refused.value)
    assert message.startswith(f"{target} holds files this command does not write")
    assert "precious.txt" in message and "sub/results.json" in message and "steps.csv" not in message
    assert "remove them or give another folder" in message
    assert tree(target) == before_tree  # nothing replaced, the previous output included
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out"]  # no temporary or old folder left
    assert atomic.WRITTEN[before_written:] == []


def test_the_refusal_names_a_few_of_many_files(tmp_path):
    target = tmp_path / "out"
    target.mkdir()
    for i in range(50):
        (target / f"photo{i:02d}.jpg").write_text("x")
    with pytest.raises(ValueError, match=r"\(photo00.jpg, photo01.jpg, photo02.jpg, \.\.\.\)"), \
            atomic_directory(target) as tmp:
        (tmp / "a.csv").write_text("x")
    assert len(list(target.iterdir())) == 50 and sorted(p.name for p in tmp_path.iterdir()) == ["out"]


def test_an_empty_folder_the_output_does_not_have_is_refused_too(tmp_path):
    target = tmp_path / "out"
    (target / "mine").mkdir(parents=True)
    with pytest.raises(ValueError, match="mine/"), atomic_directory(target) as tmp:
        (tmp / "a.csv").write_text("x")
    assert (target / "mine").is_dir() and sorted(p.name for p in tmp_path.iterdir()) == ["out"]


def test_a_previous_output_with_the_same_files_is_replaced_as_before(tmp_path):
    """What a command run again on its own output meets: the same names (an empty folder of the old output
    filled now, new files beside them), each with new content."""
    target = tmp_path / "out"
    (target / "plans").mkdir(parents=True)
    (target / "problems").mkdir()
    (target / "domain.pddl").write_text("old")
    (target / "plans" / "a.plan").write_text("old")
    with atomic_directory(target) as tmp:
        (tmp / "plans").mkdir()
        (tmp / "problems").mkdir()
        (tmp / "domain.pddl").write_text("new")
        (tmp / "plans" / "a.plan").write_text("new")
        (tmp / "problems" / "a.pddl").write_text("new")
    assert tree(target) == {"domain.pddl": "new", "plans": None, "plans/a.plan": "new", "problems": None,
                            "problems/a.pddl": "new"}
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out"]


def test_a_cache_entry_is_the_commands_own_and_is_replaced_whatever_it_holds(tmp_path):
    """A cache entry (`output=False`) that could not be read is written again under the same name: a stray file
    in it is debris of the cache, not a user's, and must not stop the command."""
    entry = tmp_path / "ab" / "abcd.steps"
    entry.mkdir(parents=True)
    (entry / "half-copied").write_text("x")
    with atomic_directory(entry, output=False) as tmp:
        (tmp / "steps.parquet").write_text("new")
    assert tree(entry) == {"steps.parquet": "new"}


def test_a_target_that_is_a_file_is_refused_before_the_block_runs(tmp_path):
    target = tmp_path / "notes.txt"
    target.write_text("mine")
    ran = []
    with pytest.raises(ValueError, match=f"{target} is a file, not a folder"), atomic_directory(target):
        ran.append(True)
    assert not ran and target.read_text() == "mine"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["notes.txt"]


@pytest.mark.parametrize("where", [".", ".."])
@pytest.mark.parametrize("holding", ["other files", "a previous output"])
def test_the_current_folder_or_its_parent_is_refused_with_no_debris(tmp_path, monkeypatch, where, holding):
    """`--output .` left a hidden temporary folder behind, `--output ..` a traceback (EBUSY); resolved, `.` holding
    only a previous output would be replaced and leave the command and its shell in a deleted folder. Both are
    refused before the block runs, whatever they hold."""
    scratch = tmp_path / "scratch"
    here = scratch / "work"
    here.mkdir(parents=True)
    (here / ("precious.txt" if holding == "other files" else "steps.csv")).write_text("mine")
    (scratch / "beside.txt").write_text("mine too")
    before = tree(scratch)
    monkeypatch.chdir(here)
    ran = []
    with pytest.raises(ValueError, match=rf"^{re.escape(where)} is the folder this command runs in, or holds it"), \
            atomic_directory(where) as tmp:
        ran.append(tmp)
    assert not ran and tree(scratch) == before and sorted(p.name for p in tmp_path.iterdir()) == ["scratch"]


def test_a_loop_of_links_is_named_in_one_line(tmp_path):
    (tmp_path / "a").symlink_to(tmp_path / "b")
    (tmp_path / "b").symlink_to(tmp_path / "a")
    with pytest.raises(ValueError, match=f"^{tmp_path / 'a'}: "), atomic_directory(tmp_path / "a"):
        pass


def an_old_output(tmp_path: Path) -> Path:
    target = tmp_path / "out"
    target.mkdir()
    (target / "a.csv").write_text("old")
    return target


def moves_go(monkeypatch, nth: int, instead) -> list[str]:
    """`os.replace` in atomic.py as it is, but for its `nth` call, which runs `instead(src, dst, real)`: another
    writer or a stop landing between the moves of a replacement. Returns the sources of the calls, in order."""
    real, calls = os.replace, []

    def replace(src, dst):
        calls.append(src)
        if len(calls) == nth:
            return instead(src, dst, real)
        return real(src, dst)

    monkeypatch.setattr(atomic.os, "replace", replace)
    return calls


def their_folder_put_in_place(src, dst, real):
    """Another process's folder lands where this one's was to go, and this one's move fails on it."""
    Path(dst).mkdir()
    (Path(dst) / "a.csv").write_text("theirs")
    raise OSError(39, "Directory not empty", os.fspath(src))


def test_another_writers_folder_put_in_place_between_the_moves_is_kept_and_no_old_copy_is_left(tmp_path, monkeypatch):
    """Two processes writing one output: when the other one's folder takes the place between this one's two moves,
    this one fails, and its copy of the old folder is removed, not left beside as `.out.old.PID`."""
    target = an_old_output(tmp_path)
    moves_go(monkeypatch, 2, their_folder_put_in_place)  # the old folder moved aside, then this one's new one fails
    with pytest.raises(OSError, match="not empty"), atomic_directory(target) as tmp:
        (tmp / "a.csv").write_text("new")
    assert tree(target) == {"a.csv": "theirs"} and sorted(p.name for p in tmp_path.iterdir()) == ["out"]


def test_a_cache_entry_another_process_wrote_first_stands(tmp_path, monkeypatch):
    """Two parallel jobs drawing the same rooms save the same cache entry: the one whose folder lands second finds
    the other's in place (the move fails: not empty), and keeps it, with no error and nothing left behind (it
    stopped a `choose_C` stage of the pipeline)."""
    target = tmp_path / "key"
    moves_go(monkeypatch, 1, their_folder_put_in_place)  # nothing to move aside: the first move is this one's
    with atomic_directory(target, output=False) as tmp:
        (tmp / "a.csv").write_text("ours")
    assert tree(tmp_path) == {"key": None, "key/a.csv": "theirs"}


def test_a_stop_between_the_two_moves_puts_the_old_folder_back(tmp_path, monkeypatch):
    """A signal can land after the old folder is moved aside and before anything says so: it goes back all the same."""
    target = an_old_output(tmp_path)

    def then_stopped(src, dst, real):
        real(src, dst)
        raise KeyboardInterrupt

    moves_go(monkeypatch, 1, then_stopped)
    with pytest.raises(KeyboardInterrupt), atomic_directory(target) as tmp:
        (tmp / "a.csv").write_text("new")
    assert tree(target) == {"a.csv": "old"} and sorted(p.name for p in tmp_path.iterdir()) == ["out"]


def test_a_file_in_the_way_of_the_folder_is_named(tmp_path):
    blocker = tmp_path / "notes.txt"
    blocker.write_text("mine")
    for target in (blocker / "sub", blocker / "sub" / "deeper"):
        with pytest.raises(ValueError, match=f"{blocker} is a file, not a folder"), atomic_directory(target):
            pass
    assert blocker.read_text() == "mine" and sorted(p.name for p in tmp_path.iterdir()) == ["notes.txt"]


def test_a_replacement_that_fails_half_way_puts_the_old_folder_back_and_removes_the_new_one(tmp_path, monkeypatch):
    """The old folder is moved aside, then the new one moved in: if that second move fails, the old one is put
    back and the temporary one removed, and the error comes out."""
    target = an_old_output(tmp_path)

    def busy(src, dst, real):
        raise OSError(16, "Device or resource busy", os.fspath(src))

    calls = moves_go(monkeypatch, 2, busy)
    with pytest.raises(OSError, match="busy"), atomic_directory(target) as tmp:
        (tmp / "a.csv").write_text("new")
    assert len(calls) == 3  # aside, in (failed), back
    assert tree(target) == {"a.csv": "old"} and sorted(p.name for p in tmp_path.iterdir()) == ["out"]


# --- a file replaced whole -------------------------------------------------------------------------------------------

def test_a_file_output_that_is_a_folder_is_refused_before_the_block_runs(tmp_path):
    folder = tmp_path / "models"
    folder.mkdir()
    (folder / "kept.npz").write_text("x")
    ran = []
    with pytest.raises(ValueError, match=f"^{folder} is a folder; give a file name$"), atomic_file(folder):
        ran.append(True)
    with pytest.raises(ValueError, match="is a folder; give a file name"):
        write_arrays(folder, {"w": np.zeros(2)})
    with pytest.raises(ValueError, match="is a folder; give a file name"):
        write_text_atomic(folder, "text")
    assert not ran and tree(tmp_path) == {"models": None, "models/kept.npz": "x"}


@pytest.mark.parametrize("under", ["m.npz", "sub/m.npz"])
def test_a_file_in_the_way_of_a_files_folder_is_named(tmp_path, under):
    blocker = tmp_path / "notes.txt"
    blocker.write_text("mine")
    with pytest.raises(ValueError, match=f"{blocker / under}: {blocker} is a file, not a folder"):
        write_arrays(blocker / under, {"w": np.zeros(2)})
    assert blocker.read_text() == "mine" and sorted(p.name for p in tmp_path.iterdir()) == ["notes.txt"]


# --- the command line ------------------------------------------------------------------------------------------------

def error_lines(err: str) -> list[str]:
    return [line for line in err.splitlines() if line.startswith("error:")]


def test_a_stage_refuses_an_output_folder_holding_an_unrelated_file(benchmark_logs, tmp_path, capsys):
    from taskseq.cli import main

    out = tmp_path / "sandbox"
    out.mkdir()
    (out / "precious.txt").write_text("mine")
    assert main(["--no-mlflow", "ingest", "--input", str(benchmark_logs), "--output", str(out)]) != 0
    err = capsys.readouterr().err
    assert len(error_lines(err)) == 1 and "Traceback" not in err
    assert error_lines(err)[0] == (f"error: {out} holds files this command does not write (precious.txt), which "
                                   "replacing the folder would delete: remove them or give another folder")
    assert err.splitlines()[-1] == "nothing was written"
    assert tree(out) == {"precious.txt": "mine"} and sorted(p.name for p in tmp_path.iterdir()) == ["sandbox"]
    # its own output, written again, is replaced: the same files, the same bytes (no marker file added)
    tables = tmp_path / "tables"

    def contents() -> dict[str, bytes]:
        return {p.name: p.read_bytes() for p in sorted(tables.iterdir())}

    assert main(["--no-mlflow", "ingest", "--input", str(benchmark_logs), "--output", str(tables)]) == 0
    written = contents()
    assert main(["--no-mlflow", "ingest", "--input", str(benchmark_logs), "--output", str(tables)]) == 0
    assert contents() == written and all(name.endswith(".parquet") for name in written)


@pytest.mark.parametrize("output", ["folder", "under a file"])
def test_a_tool_refuses_an_output_file_of_the_wrong_kind_in_one_line(tmp_path, capsys, output):
    from taskseq.cli import main

    (tmp_path / "folder").mkdir()
    (tmp_path / "notes.txt").write_text("mine")
    path = tmp_path / {"folder": "folder", "under a file": "notes.txt/layout.json"}[output]
    assert main(["layout", str(WORKSHOP), "--output", str(path)]) == 2
    err = capsys.readouterr().err
    assert "Traceback" not in err and len(err.splitlines()) == 1 and err.startswith(f"error: {path}")
    assert tree(tmp_path) == {"folder": None, "notes.txt": "mine"}


@pytest.mark.parametrize(("command", "code"), [("features", 1), ("layout", 2)])
def test_an_os_error_left_is_one_line_with_the_exit_code_of_a_bad_file(capsys, command, code):
    """What the system refuses beyond the checks above (no permission, a folder where a file goes) is a bad file
    as a missing one is: a stage exits 1 and says what it wrote, a tool exits 2."""
    from taskseq.cli import _guarded

    def body() -> int:
        raise IsADirectoryError(21, "Is a directory", "/data/out")

    assert _guarded(argparse.Namespace(command=command), body) == code
    lines = capsys.readouterr().err.splitlines()
    assert lines[0] == "error: Is a directory: /data/out"
    assert lines[1:] == (["nothing was written"] if command == "features" else [])


def test_a_closed_pipe_is_left_to_main(capsys):
    from taskseq.cli import _guarded

    def body() -> int:
        raise BrokenPipeError(32, "Broken pipe")

    with pytest.raises(BrokenPipeError):
        _guarded(argparse.Namespace(command="plan"), body)
    assert capsys.readouterr().err == ""
