"""Counts in messages agree with their number."""

import pytest

from taskseq.sim.primitives import Action
from taskseq.sim.tasks import Task
from taskseq.words import counted


@pytest.mark.parametrize(("n", "spelled", "text"), [
    (0, False, "0 sequences"), (1, False, "1 sequence"), (2, False, "2 sequences"), (12, False, "12 sequences"),
    (0, True, "no sequences"), (1, True, "one sequence"), (2, True, "two sequences"), (3, True, "3 sequences"),
])
def test_a_count_agrees_with_its_number(n, spelled, text):
    assert counted(n, "sequence", spelled) == text


def test_the_simulator_says_how_many_arguments_in_words():
    with pytest.raises(ValueError, match=r"^grasp takes one argument, got 2: \('a', 'b'\)$"):
        Action("grasp", ("a", "b"))
    with pytest.raises(ValueError, match=r"^task pick_and_place takes two arguments, got 1$"):
        Task("pick_and_place", ("a",))
