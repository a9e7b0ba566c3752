"""The order the suite's files are handed to pytest-xdist's workers in (tests/conftest.py)."""

from __future__ import annotations

from pathlib import Path
from types import SimpleNamespace

from tests.conftest import SLOWEST_FIRST, pytest_collection_modifyitems

HERE = Path(__file__).parent


def test_every_file_named_slowest_is_a_test_file_here():
    assert len(set(SLOWEST_FIRST)) == len(SLOWEST_FIRST)
    assert [name for name in SLOWEST_FIRST if not (HERE / name).is_file()] == []


def test_the_slowest_files_come_first_and_every_file_keeps_its_tests_together_in_order():
    def item(file: str, test: str) -> SimpleNamespace:
        return SimpleNamespace(path=HERE / file, name=test)

    slow, slower = SLOWEST_FIRST[1], SLOWEST_FIRST[0]
    items = [item("test_a.py", "t1"), item(slow, "t1"), item("test_a.py", "t2"), item("test_b.py", "t1"),
             item(slow, "t2"), item(slower, "t1")]
    pytest_collection_modifyitems(None, items)
    assert [(i.path.name, i.name) for i in items] == [
        (slower, "t1"), (slow, "t1"), (slow, "t2"), ("test_a.py", "t1"), ("test_a.py", "t2"), ("test_b.py", "t1")]
