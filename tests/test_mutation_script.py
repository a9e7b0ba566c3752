"""scripts/mutation.py: a recorded equivalent mutant is checked by the lines it changes, not only by its number."""

from __future__ import annotations

import importlib.util
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="module")
def mutation():
    spec = importlib.util.spec_from_file_location("mutation_script", ROOT / "scripts" / "mutation.py")
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module  # dataclasses look their module up by name
    spec.loader.exec_module(module)
    return module


NAME = "taskseq.sim.primitives.x__grasp__mutmut_39"
DIFF = """--- taskseq/sim/primitives.py
+++ taskseq/sim/primitives.py
@@ -4,6 +4,6 @@
     _require(
         state.reachable(a), action, "within reach", f"{a} is {state.reach_distance(a):.2f} m from the robot"
     )
-    state.support.pop(a, None)
+    state.support.pop(a, )
     state.held = a
---- a removed line that began with three dashes"""
RENUMBERED = DIFF.replace("pop(a, )", "pop(None, None)")


def test_a_mutants_fingerprint_is_the_lines_it_removes_and_adds(mutation):
    assert mutation.fingerprint(DIFF) == ("- state.support.pop(a, None)", "+ state.support.pop(a, )",
                                          "- --- a removed line that began with three dashes")


def test_a_recorded_equivalent_whose_name_now_means_another_mutant_stops_the_report(mutation):
    recorded = {NAME: mutation.Equivalent("the key is always there", mutation.fingerprint(DIFF)),
                "taskseq.sim.tasks.x_goal_reached__mutmut_13": mutation.Equivalent("not yet recorded")}
    mutation.check_fingerprints(recorded, {NAME: DIFF, "taskseq.sim.tasks.x_goal_reached__mutmut_13": DIFF})
    with pytest.raises(mutation.MovedMutant, match=rf"(?s)1 recorded equivalent.*{NAME}\n.*recorded: - state"
                                                   r".*now:      - state.support.pop\(a, None\) \| \+ state."
                                                   r"support.pop\(None, None\)"):
        mutation.check_fingerprints(recorded, {NAME: RENUMBERED, "taskseq.sim.tasks.x_goal_reached__mutmut_13": DIFF})


def test_fingerprints_are_filled_from_a_report_and_written_back_with_the_reasons(mutation, tmp_path):
    path = tmp_path / "equivalent.toml"
    other = "taskseq.learn.estimator.xǁStepScorerǁget_params__mutmut_1"
    path.write_text(f'"{NAME}" = "pop(a) \\"always\\" finds a"\n"{other}" = "another group"\n')
    report = tmp_path / "primitives.md"
    report.write_text(f"# Mutation testing\n\n## Survivors\n\n### `x` (survived)\n\n```diff\n+ a\n```\n\n"
                      f"## Equivalent mutants\n\n### `{NAME}`\n\nwhy\n\n```diff\n{DIFF}\n```\n")
    assert mutation.fill_fingerprints("primitives", report, path) == [NAME]
    entries = mutation._equivalent(path)
    assert entries == {NAME: mutation.Equivalent('pop(a) "always" finds a', mutation.fingerprint(DIFF)),
                       other: mutation.Equivalent("another group")}
    assert mutation.fill_fingerprints("primitives", report, path) == []  # recorded once


def test_every_recorded_equivalent_has_the_lines_its_groups_report_shows(mutation):
    entries = mutation._equivalent()
    assert entries and all(e.mutation for e in entries.values())
    for name, group in mutation.GROUPS.items():
        diffs = mutation.report_diffs((ROOT / "reports" / "mutation" / f"{name}.md").read_text())
        mine = {m: e for m, e in entries.items() if mutation._module(m) in group.dotted()}
        assert set(diffs) == set(mine), name
        mutation.check_fingerprints(mine, diffs)
