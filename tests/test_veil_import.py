"""`taskseq veil import` on the invented fixture: end to end, noisy steps counted, malformed files refused."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import pytest

from taskseq.cli import main
from taskseq.veil import ingest
from taskseq.veil.grounding import Step
from taskseq.veil.ingest import TABLES, import_release, read_tables
from taskseq.veil.release import read_release
from taskseq.veil.replay import replay_release
from taskseq.veil.xmltree import VeilFormatError

FIXTURES = Path(__file__).parent / "fixtures" / "veil"
RELEASE = FIXTURES / "release"
FILES = [f"{t}.parquet" for t in TABLES] + ["import.json"]


@pytest.fixture(scope="module")
def imported(tmp_path_factory):
    out = tmp_path_factory.mktemp("veil") / "import"
    summary = import_release(RELEASE, out)
    return out, summary


def test_the_fixture_imports_and_replays_end_to_end(imported):
    out, summary = imported
    assert sorted(p.name for p in out.iterdir()) == sorted(FILES)
    t = {k: v.to_pylist() for k, v in read_tables(out).items()}
    seqs = {s["seq_id"]: s for s in t["sequences"]}
    assert list(seqs) == ["p001", "p002", "p003", "p004", "p005", "p006"]
    tea = seqs["p001"]
    assert (tea["environment"], tea["room"], tea["env_number"], tea["objective"]) == (
        "kitchen_scenario_environment_number_1", "kitchen", 1, "Hot Tea")
    assert (tea["n_steps"], tea["n_kept"], tea["n_skipped"], tea["status"], tea["n_segments"]) == (11, 11, 0,
                                                                                                   "complete", 2)
    living = seqs["p003"]  # living_room_scenario_environment_number9 is livingRoom1.xml
    assert (living["room"], living["env_number"], living["status"]) == ("livingRoom", 1, "complete")
    assert [s["status"] for s in seqs.values()] == ["complete", "partial", "complete", "no steps",
                                                     "no executable step", "complete"]
    steps = [s for s in t["steps"] if s["seq_id"] == "p001"]
    assert [s["segment"] for s in steps] == [0] * 5 + [1] * 6
    assert [s["kept_index"] for s in steps] == list(range(11))
    keep = steps[8]
    assert (keep["raw"], keep["verb"], keep["a1"], keep["a2"], keep["action"]) == (
        "keep Teapot_1 On HotPlate_1", "keep_on", "Teapot_1", "HotPlate_1", "keep_On_HotPlate1")
    bench = [s for s in t["steps"] if s["seq_id"] == "p003" and s["verb"] == "keep_on"][0]
    assert (bench["a1"], bench["a2"]) == ("player_1", "bench_1")  # the environment's spelling
    objects = [o for o in t["objects"] if o["environment"] == "kitchen_scenario_environment_number_1"]
    assert len(objects) == 15
    beaker = next(o for o in objects if o["name"] == "Beaker_2")
    assert (beaker["category"], beaker["catalogued"], beaker["affordances"]) == ("Beaker", True,
                                                                                 ["IsGraspable", "IsPourable"])
    assert (beaker["x"], beaker["y"], beaker["z"], beaker["true_states"]) == (14.0, 40.0, -3.0, ["Tea"])
    assert beaker["other_states"] == [{"name": "Shade", "value": "Blue"}]
    assert summary == json.loads((out / "import.json").read_text())
    assert (summary["sequences"], summary["sequences_imported"], summary["steps"]) == (6, 4, 60)


def test_a_noisy_sequences_skipped_steps_are_counted_by_reason_and_its_other_steps_kept(imported):
    out, summary = imported
    steps = [s for s in read_tables(out)["steps"].to_pylist() if s["seq_id"] == "p002"]
    skipped = [(s["raw"], s["reason"]) for s in steps if s["status"] == "skipped"]
    assert skipped == [("grasp Ghost_1", "unknown object"), ("grasp Beaker_2", "not near"),
                       ("grasp Honey_1", "hands full"), ("release Teapot_1", "not grasping")]
    kept = [s for s in steps if s["status"] == "kept"]
    assert [s["kept_index"] for s in kept] == list(range(8))
    assert [s["raw"] for s in kept][-2:] == ["moveto Tub", "keep Beaker_2 On Tub"]
    assert summary["skipped_by_reason"] == {"not grasping": 2, "unknown object": 2, "hands full": 1, "not near": 1}
    assert summary["steps_kept"] + summary["steps_skipped"] == summary["steps"]
    assert summary["sequences_by_status"] == {"complete": 3, "partial": 1, "no executable step": 1, "no steps": 1}


def test_replay_keeps_the_state_before_each_kept_step():
    release = read_release(RELEASE)
    [noisy] = replay_release(release, [p for p in release.points if p.seq_id == "p002"])
    assert len(noisy.states) == len(noisy.kept) == 8
    assert noisy.states[0] == noisy.initial
    before_keep = noisy.states[-1]
    assert before_keep.grasped() == ("Beaker_2",)  # Beaker_1 released, Honey_1 never grasped (hands full)
    assert noisy.kept[-1] == Step("keep_on", "Beaker_2", "Tub")
    assert noisy.final.holds("On", "Beaker_2", "Tub")
    assert [r.status for r in noisy.records].count("skipped") == 4


def test_two_imports_give_identical_bytes(imported, tmp_path):
    out, _ = imported
    again = tmp_path / "again"
    import_release(RELEASE, again)
    for name in FILES:
        assert (again / name).read_bytes() == (out / name).read_bytes(), name


def test_another_release_folder_imports_on_its_own(tmp_path):
    summary = import_release(FIXTURES / "release_other", tmp_path / "other")
    seqs = read_tables(tmp_path / "other")["sequences"].to_pylist()
    assert [(s["environment"], s["room"], s["env_number"]) for s in seqs] == [
        ("kitchen_scenario_environment_number_3", "kitchen", 3),
        ("living_room_scenario_environment_number8", "livingRoom", 2)]
    assert summary["skipped_by_reason"] == {"not grasping": 1}
    assert summary["steps_kept"] == 9


def test_the_command_imports_and_says_what_it_kept(tmp_path, capsys):
    assert main(["veil", "import", "--release", str(RELEASE), "--output", str(tmp_path / "o"), "--quiet"]) == 0
    out = capsys.readouterr().out
    assert "4 of 6 sequences imported" in out and "54 of 60 steps kept, 6 skipped" in out


def _broken(tmp_path: Path, file: str, old: str, new: str) -> Path:
    copy = tmp_path / "release"
    shutil.copytree(RELEASE, copy)
    path = copy / file
    text = path.read_text()
    assert old in text
    path.write_text(text.replace(old, new, 1))
    return copy


BROKEN = {
    "bad xml": ("Environments/kitchen/kitchen2.xml", "<object><name>Beaker_1</name>", "<object><name>Beaker_1<name>",
                "Environments/kitchen/kitchen2.xml", 3, "(xml)"),
    "unknown environment id": ("data.xml", "<environment>kitchen_scenario_environment_number_2</environment>",
                               "<environment>kitchen_number_2</environment>", "data.xml", 23, "<environment>"),
    "environment without a file": ("data.xml", "kitchen_scenario_environment_number_2",
                                   "kitchen_scenario_environment_number_7", "data.xml", 21, "<environment>"),
    "bad position": ("Environments/kitchen/kitchen1.xml", "<position>12.5,40,-3</position>",
                     "<position>12.5,forty,-3</position>", "Environments/kitchen/kitchen1.xml", 3, "<position>"),
    "missing element": ("Environments/livingRoom/livingRoom1.xml", "<rotation>(0, 45, 0)</rotation>", "",
                        "Environments/livingRoom/livingRoom1.xml", 6, "<object>"),
    "unknown action": ("data.xml", "<action>turn TubKnob</action>", "<action>spin TubKnob</action>",
                       "data.xml", 11, "<action>"),
    "bad domain": ("domainKnowledge.pddl", "(:action release :parameters (?o)", "(:action release :parameters (o)",
                   "domainKnowledge.pddl", 25, "(:action release)"),
}


@pytest.mark.parametrize("case", list(BROKEN))
def test_a_malformed_release_names_file_line_and_element_and_writes_nothing(tmp_path, capsys, case):
    file, old, new, where, line, element = BROKEN[case]
    broken = _broken(tmp_path, file, old, new)
    with pytest.raises(VeilFormatError) as err:
        import_release(broken, tmp_path / "out")
    assert (err.value.path, err.value.line, err.value.element) == (str(broken / where), line, element)
    assert not (tmp_path / "out").exists()
    keep = tmp_path / "existing"
    keep.mkdir()
    (keep / "mine.txt").write_text("untouched")
    assert main(["veil", "import", "--release", str(broken), "--output", str(keep), "--quiet"]) == 2
    lines = capsys.readouterr().err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith(f"error: {broken / where}:{line}: {element}:")
    assert [p.name for p in keep.iterdir()] == ["mine.txt"]
    assert [p.name for p in tmp_path.iterdir() if p.name.startswith(".")] == []


def test_the_counts_a_report_holds_name_no_state_of_the_release():
    """Reasons that name a state (`not state S`, `state S`) are counted together; the others stay as they are."""
    summary = {"sequences": 4, "sequences_imported": 3, "sequences_by_status": {"complete": 3, "no steps": 1},
               "steps": 20, "steps_kept": 14, "steps_skipped": 6, "environments": 2, "objects": 9,
               "steps_by_verb": {"grasp": {"kept": 1, "skipped": 0}}, "categories_not_in_objects_xml": ["Samovar"],
               "skipped_by_reason": {"not near": 2, "not state LidIsOpen": 2, "state Steeped": 1, "hands full": 1}}
    counts = ingest.counts_without_names(summary)
    assert counts["skipped_by_reason"] == {"a state the step needs": 3, "not near": 2, "hands full": 1}
    assert sum(counts["skipped_by_reason"].values()) == counts["steps_skipped"]
    text = json.dumps(counts)
    assert all(name not in text for name in ("LidIsOpen", "Steeped", "Samovar", "grasp"))
