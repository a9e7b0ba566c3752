"""runtime/atomic.py on hand-made files: a reader sees the old result or the new one, never half of one, and no
temporary file or folder is left behind, whether the writer succeeds or raises."""

from __future__ import annotations

import codecs
import json
import os
import pathlib
import shutil
import zipfile

import numpy as np
import pytest

from taskseq.runtime import atomic
from taskseq.runtime.atomic import atomic_directory, atomic_file, write_arrays, write_json_atomic, write_text_atomic


class Planted(Exception):
    """The error a writer raises part way."""


def listing(folder):
    return sorted(p.name for p in folder.iterdir())


# --- atomic_file ---------------------------------------------------------------------------------------------------

def test_a_file_is_replaced_only_when_the_block_ends_and_the_temporary_path_sits_beside_it(tmp_path):
    path = tmp_path / "model.npz"
    path.write_bytes(b"old")
    before = len(atomic.WRITTEN)
    with atomic_file(path) as tmp:
        assert tmp != path and tmp.parent == tmp_path
        assert tmp.name.startswith(".model.") and tmp.suffix == ".npz"  # hidden, and the writer's suffix
        assert tmp.exists() and tmp.read_bytes() == b""
        tmp.write_bytes(b"new")
        assert path.read_bytes() == b"old"  # nothing seen before the block ends
    assert path.read_bytes() == b"new"
    assert listing(tmp_path) == ["model.npz"]
    assert atomic.WRITTEN[before:] == [path]


def test_a_writer_that_raises_leaves_the_old_file_and_no_temporary_file(tmp_path):
    path = tmp_path / "table.csv"
    path.write_text("old\n")
    before = len(atomic.WRITTEN)
    with pytest.raises(Planted), atomic_file(path) as tmp:
        tmp.write_text("half of the n")
        raise Planted
    assert path.read_text() == "old\n"
    assert listing(tmp_path) == ["table.csv"]
    assert atomic.WRITTEN[before:] == []


def test_an_interrupt_part_way_also_leaves_no_temporary_file(tmp_path):
    path = tmp_path / "a.txt"
    with pytest.raises(KeyboardInterrupt), atomic_file(path) as tmp:
        tmp.write_text("x")
        raise KeyboardInterrupt
    assert listing(tmp_path) == []


def test_the_writers_own_error_comes_out_even_when_it_removed_the_temporary_file(tmp_path):
    path = tmp_path / "a.txt"
    with pytest.raises(Planted), atomic_file(path) as tmp:
        tmp.unlink()
        raise Planted
    assert listing(tmp_path) == []


def test_a_missing_folder_is_made_and_an_existing_one_is_fine(tmp_path):
    path = tmp_path / "deep" / "er" / "a.txt"
    with atomic_file(path) as tmp:
        tmp.write_text("one")
    with atomic_file(path) as tmp:
        tmp.write_text("two")
    assert path.read_text() == "two"
    assert listing(path.parent) == ["a.txt"]


def test_write_text_atomic_writes_exactly_the_texts_utf8_bytes(tmp_path):
    path = tmp_path / "sub" / "notes.md"
    text = "über\r\nline two\n\tend ✓"
    write_text_atomic(path, text)
    assert path.read_bytes() == text.encode("utf-8")
    write_text_atomic(str(path), "short")  # a string path too, and a shorter text leaves no tail of the longer one
    assert path.read_bytes() == b"short"
    assert listing(path.parent) == ["notes.md"]


def test_the_text_is_encoded_as_utf8_whatever_the_locale(tmp_path, monkeypatch):
    """The locale's encoding differs between machines (ASCII under a bare C locale): the text must not depend on it."""
    encodings = []
    real = pathlib.Path.write_text

    def spy(self, data, encoding=None, *args, **kwargs):
        encodings.append(encoding)
        return real(self, data, encoding, *args, **kwargs)

    monkeypatch.setattr(pathlib.Path, "write_text", spy)
    write_text_atomic(tmp_path / "a.txt", "é")
    assert len(encodings) == 1 and encodings[0] is not None and codecs.lookup(encodings[0]).name == "utf-8"


def test_write_json_atomic_writes_sorted_indented_json_with_a_final_newline(tmp_path):
    path = tmp_path / "s.json"
    write_json_atomic(path, {"b": [1, 2], "a": {"y": 1.5, "x": None}})
    assert path.read_text() == '{\n  "a": {\n    "x": null,\n    "y": 1.5\n  },\n  "b": [\n    1,\n    2\n  ]\n}\n'
    assert json.loads(path.read_text()) == {"a": {"x": None, "y": 1.5}, "b": [1, 2]}


def test_a_json_value_that_cannot_be_written_leaves_the_old_file(tmp_path):
    path = tmp_path / "s.json"
    path.write_text("{}\n")
    with pytest.raises(TypeError):
        write_json_atomic(path, {"a": object()})
    assert path.read_text() == "{}\n"
    assert listing(tmp_path) == ["s.json"]


def test_write_arrays_round_trips_without_pickles_and_gives_the_same_bytes_for_the_same_arrays(tmp_path):
    arrays = {"w": np.arange(6, dtype=np.float64).reshape(2, 3), "ids": np.array([3, 1, 2], dtype=np.int32)}
    first, second = tmp_path / "a.npz", tmp_path / "b" / "b.npz"
    write_arrays(first, arrays)
    write_arrays(second, {k: v.copy() for k, v in arrays.items()})
    assert first.read_bytes() == second.read_bytes()
    with np.load(first, allow_pickle=False) as z:
        assert sorted(z.files) == ["ids", "w"]
        for name, array in arrays.items():
            assert z[name].dtype == array.dtype and np.array_equal(z[name], array)
    with zipfile.ZipFile(first) as z:
        infos = z.infolist()
    assert [i.filename for i in infos] == ["w.npy", "ids.npy"]
    assert all(i.date_time == (1980, 1, 1, 0, 0, 0) and i.compress_type == zipfile.ZIP_STORED for i in infos)
    assert listing(tmp_path) == ["a.npz", "b"] and listing(tmp_path / "b") == ["b.npz"]


def test_write_arrays_refuses_an_object_array_and_keeps_the_old_file(tmp_path):
    path = tmp_path / "a.npz"
    path.write_bytes(b"old")
    with pytest.raises(ValueError):
        write_arrays(path, {"ok": np.zeros(2), "bad": np.array([{"a": 1}], dtype=object)})
    assert path.read_bytes() == b"old"
    assert listing(tmp_path) == ["a.npz"]


# --- atomic_directory ----------------------------------------------------------------------------------------------

def test_a_folder_is_replaced_whole_when_the_block_ends(tmp_path):
    target = tmp_path / "out"
    target.mkdir()
    (target / "new.txt").write_text("stale")  # a previous output of the same writer: the same file names
    before = len(atomic.WRITTEN)
    with atomic_directory(target) as tmp:
        assert tmp.is_dir() and tmp.parent == tmp_path and tmp.name.startswith(".out.")
        assert listing(tmp) == []
        (tmp / "new.txt").write_text("new")
        assert (target / "new.txt").read_text() == "stale"  # the old folder until the block ends
    assert listing(target) == ["new.txt"] and (target / "new.txt").read_text() == "new"
    assert listing(tmp_path) == ["out"]  # neither the temporary folder nor the old one is left
    assert atomic.WRITTEN[before:] == [target]


def test_the_old_folder_is_moved_aside_to_a_hidden_name_beside_it_before_the_new_one_takes_its_place(tmp_path,
                                                                                                    monkeypatch):
    target = tmp_path / "out"
    target.mkdir()
    moves = []
    real = os.replace

    def spy(src, dst):
        moves.append((os.fspath(src), os.fspath(dst)))
        real(src, dst)

    monkeypatch.setattr(atomic.os, "replace", spy)
    with atomic_directory(target) as tmp:
        (tmp / "a").write_text("a")
    assert len(moves) == 2
    (old_src, old_dst), (new_src, new_dst) = moves
    assert old_src == os.fspath(target)
    assert os.path.dirname(old_dst) == os.fspath(tmp_path)
    assert os.path.basename(old_dst) == f".out.old.{os.getpid()}"
    assert (new_src, new_dst) == (os.fspath(tmp), os.fspath(target))
    assert listing(tmp_path) == ["out"]


def test_a_new_folder_is_made_where_there_was_none_even_under_missing_folders(tmp_path):
    target = tmp_path / "a" / "b" / "out"
    with atomic_directory(str(target)) as tmp:
        (tmp / "x").write_text("x")
    assert listing(target) == ["x"]
    assert listing(target.parent) == ["out"]
    with atomic_directory(target) as tmp:  # the folder above exists now
        (tmp / "x").write_text("y")
    assert listing(target) == ["x"] and (target / "x").read_text() == "y"


def test_a_writer_that_raises_leaves_the_old_folder_and_no_temporary_folder(tmp_path):
    target = tmp_path / "out"
    target.mkdir()
    (target / "kept.txt").write_text("kept")
    before = len(atomic.WRITTEN)
    with pytest.raises(Planted), atomic_directory(target) as tmp:
        (tmp / "half").mkdir()
        (tmp / "half" / "file").write_text("h")
        raise Planted
    assert listing(target) == ["kept.txt"] and (target / "kept.txt").read_text() == "kept"
    assert listing(tmp_path) == ["out"]
    assert atomic.WRITTEN[before:] == []


def test_the_folder_writers_own_error_comes_out_even_when_it_removed_the_temporary_folder(tmp_path):
    target = tmp_path / "out"
    with pytest.raises(Planted), atomic_directory(target) as tmp:
        tmp.rmdir()
        raise Planted
    assert listing(tmp_path) == []


def test_an_interrupt_in_a_folder_writer_leaves_no_folder(tmp_path):
    with pytest.raises(KeyboardInterrupt), atomic_directory(tmp_path / "out") as tmp:
        (tmp / "x").write_text("x")
        raise KeyboardInterrupt
    assert listing(tmp_path) == []


@pytest.mark.parametrize("umask", [0o022, 0o002, 0o077])
def test_a_new_output_takes_the_permissions_open_would_give_it(tmp_path, monkeypatch, umask):
    monkeypatch.setattr(atomic, "_UMASK", umask)
    atomic.write_text_atomic(tmp_path / "report.md", "hello\n")
    with atomic.atomic_directory(tmp_path / "tables") as tmp:
        (tmp / "a.csv").write_text("x\n")
    assert (tmp_path / "report.md").stat().st_mode & 0o777 == 0o666 & ~umask
    assert (tmp_path / "tables").stat().st_mode & 0o777 == 0o777 & ~umask


def test_a_replaced_output_keeps_its_permissions(tmp_path):
    path, folder = tmp_path / "model.npz", tmp_path / "store"
    path.write_text("old")
    folder.mkdir()
    os.chmod(path, 0o640)
    os.chmod(folder, 0o750)
    atomic.write_text_atomic(path, "new")
    with atomic.atomic_directory(folder) as tmp:
        (tmp / "m").write_text("x")
    assert path.stat().st_mode & 0o777 == 0o640 and folder.stat().st_mode & 0o777 == 0o750


@pytest.mark.parametrize("where", ["same", "parent", "spelled otherwise"])
def test_a_command_never_replaces_the_folder_it_reads(benchmark_logs, tmp_path, capsys, where):
    """`ingest --output` equal to its `--input` (or a folder holding it) would replace the logs it read with their
    tables: it is refused before anything is written, and the logs stay."""
    from taskseq.cli import main

    logs = tmp_path / "logs"
    shutil.copytree(benchmark_logs, logs)
    before = sorted(p.name for p in logs.iterdir())
    output = {"same": logs, "parent": tmp_path, "spelled otherwise": logs / ".." / "logs"}[where]
    assert main(["--no-mlflow", "ingest", "--input", str(logs), "--output", str(output)]) == 2
    err = capsys.readouterr().err
    assert f"--output {output} would replace --input {logs}, which this command reads" in err
    assert err.splitlines()[-1] == "nothing was written"
    assert sorted(p.name for p in logs.iterdir()) == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["logs"]


def test_features_fold_models_and_pddl_refuse_an_output_that_holds_their_input(tmp_path, capsys):
    from taskseq.cli import main

    tables = tmp_path / "world" / "processed"
    tables.mkdir(parents=True)
    assert main(["--no-mlflow", "features", "--input", str(tables), "--output", str(tmp_path / "world")]) == 2
    assert "would replace --input" in capsys.readouterr().err
    assert main(["--no-mlflow", "fold_models", "--features", str(tmp_path / "world" / "features"), "--processed",
                 str(tables), "--output", str(tmp_path / "world")]) == 2
    assert "would replace --features" in capsys.readouterr().err
    assert main(["--no-mlflow", "pddl", "--processed", str(tables), "--output", str(tmp_path / "world")]) == 2
    assert "would replace --processed" in capsys.readouterr().err
    assert tables.is_dir()


@pytest.mark.parametrize("command", ["import", "evaluate"])
def test_veil_commands_refuse_an_output_that_holds_the_release(tmp_path, capsys, command):
    """`taskseq veil import|evaluate --output` at or above the release folder would delete the release (which is
    never committed, so nothing could bring it back): refused before anything is read or written, the release whole."""
    from taskseq.cli import main

    release = tmp_path / "shared" / "veil500"
    shutil.copytree(pathlib.Path(__file__).parent / "fixtures" / "veil" / "release", release)
    before = sorted(str(p.relative_to(release)) for p in release.rglob("*"))
    assert main(["--no-mlflow", "veil", command, "--release", str(release), "--output",
                 str(tmp_path / "shared")]) == 2
    assert f"would replace --release {release}, which this command reads" in capsys.readouterr().err
    assert sorted(str(p.relative_to(release)) for p in release.rglob("*")) == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["shared"]


def test_veil_evaluate_refuses_an_output_that_holds_its_model_or_its_recordings(tmp_path, capsys):
    from taskseq.cli import main

    release = pathlib.Path(__file__).parent / "fixtures" / "veil" / "release"
    out = tmp_path / "out"
    out.mkdir()
    (out / "veil.npz").write_bytes(b"a model")
    assert main(["--no-mlflow", "veil", "evaluate", "--release", str(release), "--output", str(out),
                 "--model", str(out / "veil.npz")]) == 2
    assert f"would replace --model {out / 'veil.npz'}" in capsys.readouterr().err
    assert main(["--no-mlflow", "veil", "evaluate", "--release", str(release), "--output", str(out),
                 "--recordings-dir", str(out / "recordings")]) == 2
    assert f"--recordings-dir {out / 'recordings'} lies in --output {out}" in capsys.readouterr().err
    assert sorted(p.name for p in out.iterdir()) == ["veil.npz"] and (out / "veil.npz").read_bytes() == b"a model"
