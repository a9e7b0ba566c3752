"""scripts/cue_fidelity.py: the cue columns against the demonstrator's choices, on a world that is never reported."""

from __future__ import annotations

import importlib.util
from pathlib import Path

import pytest

from taskseq.settings import Generate
from taskseq.sim.scenarios import world_scenarios

ROOT = Path(__file__).resolve().parents[1]
spec = importlib.util.spec_from_file_location("cue_fidelity", ROOT / "scripts" / "cue_fidelity.py")
cue_fidelity = importlib.util.module_from_spec(spec)
spec.loader.exec_module(cue_fidelity)


def test_the_stirrer_cue_at_the_demonstrators_margin_marks_its_stirrer_in_every_stir_scenario():
    exact, seen = cue_fidelity.tally(world_scenarios(Generate(100))[0])
    assert seen["stir"] > 10 and seen["pour"] > 10 and seen["throw_away"] > 10
    # the demonstrator wants 4 cm out of the cup: that column is right every time, the others are not
    assert exact["shortest_over_container_by_0.04m"] == seen["stir"]
    assert exact["shortest_over_container_by_0.1m"] < seen["stir"]
    # a vessel holds 0.6 of its box: 1.7 times the liquid's volume is the step that finds the demonstrator's vessel
    best = max((c for c in exact if c.startswith("smallest_empty")), key=lambda c: exact[c])
    assert best == "smallest_empty_ge_1.7x_object"


def test_a_reported_world_is_refused(capsys):
    with pytest.raises(SystemExit):
        cue_fidelity.main(["--seeds", "0", "100"])
    assert "--seeds [0] are reported worlds" in capsys.readouterr().err
