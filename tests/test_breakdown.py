"""A method's programs per world seed and environment or task, on hand-made programs with known answers."""

from __future__ import annotations

import pytest

from taskseq.report.breakdown import GroupOutcome, breakdown_markdown, group_outcomes


def _program(method: str, scenario: str, kind: str) -> dict[str, str]:
    """One row as `crossval_sequences.csv` holds it (only the columns the table reads)."""
    return {"method": method, "scenario": scenario, "task": scenario.split("/")[1].split("(")[0],
            "failure": kind, "arg_correct": "1" if kind == "exact" else "0"}


# world 0: env01 all exact; env02 one exact of three, wrong object twice
# world 7: env01 one exact of four (wrong object 1, other success 2); env02 two programs, one exact, one step cap
# another method's programs, all failed, must not count
PROGRAMS = {
    0: [_program("full", "env01/stir(obj31)", "exact"), _program("full", "env01/pour(obj27)", "exact"),
        _program("full", "env02/stir(obj33)", "exact"), _program("full", "env02/pour(obj29)", "wrong_object"),
        _program("full", "env02/pick_and_place(obj34,obj01)", "wrong_object"),
        _program("relations", "env01/stir(obj31)", "stopped_late")],
    7: [_program("full", "env01/stir(obj31)", "exact"), _program("full", "env01/pour(obj27)", "other_success"),
        _program("full", "env01/pour(obj29)", "other_success"),
        _program("full", "env01/pick_and_place(obj37,obj01)", "wrong_object"),
        _program("full", "env02/stir(obj33)", "exact"), _program("full", "env02/pour(obj28)", "step_cap")],
}


def test_per_environment_counts_exact_programs_and_the_leading_other_kind():
    got = group_outcomes(PROGRAMS, "full", "environment")
    assert got == [GroupOutcome(0, "env01", 2, 2, None, 0), GroupOutcome(0, "env02", 3, 1, "wrong_object", 2),
                   GroupOutcome(7, "env01", 4, 1, "other_success", 2), GroupOutcome(7, "env02", 2, 1, "step_cap", 1)]
    assert [o.sequence_arg for o in got] == [100.0, pytest.approx(100 / 3), 25.0, 50.0]


def test_per_task_and_ties_go_to_the_earlier_kind():
    got = {(o.world_seed, o.group): o for o in group_outcomes(PROGRAMS, "full", "task")}
    assert sorted(got) == [(0, "pick_and_place"), (0, "pour"), (0, "stir"), (7, "pick_and_place"), (7, "pour"),
                           (7, "stir")]
    assert got[0, "stir"] == GroupOutcome(0, "stir", 2, 2, None, 0)
    # world 7's pours: other success twice, step cap once
    assert got[7, "pour"] == GroupOutcome(7, "pour", 3, 0, "other_success", 2)
    one_each = {0: [_program("full", "env01/pour(obj1)", "step_cap"), _program("full", "env01/pour(obj2)",
                                                                                "wrong_primitive")]}
    assert group_outcomes(one_each, "full", "task")[0].leading == "wrong_primitive"  # listed before step_cap


def test_the_table_has_a_row_per_group_and_a_column_per_seed():
    text = breakdown_markdown(group_outcomes(PROGRAMS, "full", "environment"), "The full model", "environment")
    assert text.splitlines() == [
        "The full model per environment and world seed: sequence arg, % (exact programs / programs), and the most "
        "frequent other kind (programs).", "",
        "| environment | world 0 | world 7 |", "|---|---|---|",
        "| env01 | 100.0 (2/2) | 25.0 (1/4), other success 2 |",
        "| env02 | 33.3 (1/3), wrong object 2 | 50.0 (1/2), step cap 1 |"]
    env01_only = {0: PROGRAMS[0][:2], 7: PROGRAMS[7]}  # a group a seed lacks leaves its cell empty
    lines = breakdown_markdown(group_outcomes(env01_only, "full", "environment"), "m", "environment").splitlines()
    assert lines[-1] == "| env02 |  | 50.0 (1/2), step cap 1 |"


def test_a_method_without_programs_gives_no_table():
    assert group_outcomes(PROGRAMS, "chance", "task") == []
    assert breakdown_markdown([], "The full model", "task") == ""


def test_bad_rows_are_named():
    with pytest.raises(ValueError, match="not 'room'"):
        group_outcomes(PROGRAMS, "full", "room")
    bad_kind = {3: [_program("full", "env01/stir(obj31)", "lost")]}
    with pytest.raises(ValueError, match=r"world seed 3, full, env01: unknown program kinds \['lost'\]"):
        group_outcomes(bad_kind, "full", "environment")
    bad_flag = {3: [{**_program("full", "env01/stir(obj31)", "exact"), "arg_correct": "yes"}]}
    with pytest.raises(ValueError, match=r"world seed 3: program env01/stir\(obj31\) of full: arg_correct is 'yes'"):
        group_outcomes(bad_flag, "full", "environment")
