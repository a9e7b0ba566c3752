"""`taskseq layout`: an environment file from a layout of new objects, readable by serve and plan; clear errors."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
import yaml

from taskseq.cli import main
from taskseq.serve.environments import file_environment
from taskseq.serve.layout import environment_from_layout
from taskseq.sim.scenarios import doable_tasks

EXAMPLE = Path(__file__).resolve().parents[1] / "docs" / "examples" / "workshop.yaml"


def test_the_workshop_example_is_an_environment_with_tasks_to_demonstrate(tmp_path, capsys):
    out = tmp_path / "workshop.json"
    assert main(["layout", str(EXAMPLE), "--output", str(out)]) == 0
    assert "16 objects" in capsys.readouterr().out
    env = file_environment(out.name, out.read_text())
    assert env.state.support["green_tea"] == ("thermos", "inside")
    assert env.state.support["wrench"] == ("rag", "on")
    names = {str(t) for t, _ in doable_tasks(env.state)}
    assert {"stir(broth)", "pour(green_tea)", "throw_away(rag)"} <= names


def layout(edit):
    data = yaml.safe_load(EXAMPLE.read_text())
    edit(data)
    return data


@pytest.mark.parametrize("edit, message", [
    (lambda d: d["objects"][3].pop("size"), "objects[3]: missing field 'size'"),
    (lambda d: d["objects"][3].update(size=[0.1, 0.1]), "objects[3].size: expected [width, length, height] in "
                                                        "metres, got [0.1, 0.1]"),
    # a value of the wrong type is named by its field and given whole (a string was cut to its first letter)
    (lambda d: d["objects"][3].update(size="big"), "objects[3].size: expected [width, length, height] in metres, "
                                                   "got 'big'"),
    (lambda d: d["objects"][3].update(size=[0.1, "wide", 0.2]), "objects[3].size: expected [width, length, "
                                                                "height] in metres, got 'wide'"),
    (lambda d: d["objects"][1].update(levels="three"), "objects[1].levels: expected a list of shelf heights"),
    (lambda d: d.update(robot_x="abc"), "layout: robot_x: expected an x in metres, got 'abc'"),
    (lambda d: d["furniture"].update(workbench="middle"), "layout: furniture.workbench: expected an x in metres, "
                                                          "got 'middle'"),
    (lambda d: d["items"][0].update(dx="left"), "items[0].dx: expected an offset in metres, got 'left'"),
    (lambda d: d["items"][0].update(dx=float("nan")), "items[0].dx: expected an offset in metres, got nan"),
    (lambda d: d["items"][8].update(level=1.5), "items[8].level: expected a whole number, got 1.5"),
    (lambda d: d["items"][0].update(back="yes"), "items[0].back: expected true or false, got 'yes'"),
    (lambda d: d["objects"][3].update(category="spaceship"), "unknown category 'spaceship'"),
    (lambda d: d["objects"][3].update(category="spaceship"), "objects[3].category: unknown category 'spaceship'; "
                                                             "one of beaker, bin, bottle"),
    (lambda d: d["objects"][3].update(flags=["shiny"]), "objects[3].flags: unknown flag 'shiny'; any of cylinder"),
    (lambda d: d["objects"][3].update(id="../x"), "objects[3].id"),
    (lambda d: d["objects"][3].update(name="flask, steel"), "objects[3].name: 'flask, steel': a task names an object "
                                                            "by its name"),
    (lambda d: d["objects"][3].update(name="flask (big)"), "objects[3].name: 'flask (big)'"),
    (lambda d: d["objects"][3].update(name=" "), "objects[3].name: ' '"),
    (lambda d: d["objects"][3].update(name="flask "), "objects[3].name: 'flask ': a task names an object by its name "
                                                      "(`pour(green_tea)`), so a name has no '(', ')' or ',' and no "
                                                      "space at either end"),
    (lambda d: d["items"][0].update(colour="red"), "items[0]: unknown field 'colour'"),
    (lambda d: d["items"][0].update(at="sofa"), "items[0].at: 'sofa' is neither listed in objects nor a catalog"),
    (lambda d: d["items"][0].update(at="obj10"), "items[0].at: obj10 is placed nowhere itself"),
    (lambda d: d["objects"].append({"id": "mug2", "name": "mug", "category": "mug", "size": [0.08, 0.08, 0.1]}),
     "objects[15]: mug2 is listed but placed nowhere; give it an x under furniture, or an entry under items"),
    (lambda d: d["items"][1].update(at="workbench"), "items[1].at: green_tea is a liquid; it goes in a container"),
    (lambda d: d["items"][8].update(level=7), "items[8].level: 7: tool_rack (tool_rack) has levels 0 to 2"),
    # a negative level counted from the top, and an offset left the item hanging beside its support
    (lambda d: d["items"][8].update(level=-1), "items[8].level: -1: tool_rack"),
    (lambda d: d["items"][0].update(dx=50), "items[0].dx: 50 m puts thermos off workbench (workbench): at most"),
    (lambda d: d["items"].append({"id": "obj41", "at": "rag"}), "obj41 (0.42 m wide) is wider than rag"),
    (lambda d: d["furniture"].update(sofa=3.0), "'sofa' is placed but is neither listed"),
    (lambda d: d["items"][2].update(dx=-0.6), "beaker and thermos overlap on workbench"),
    (lambda d: d["furniture"].update(tool_rack=0.3), "layout: tool_rack and workbench overlap on the floor"),
])
def test_a_bad_layout_names_its_field(edit, message):
    with pytest.raises(ValueError) as err:
        environment_from_layout(layout(edit))
    assert message in str(err.value)


def test_the_layout_command_reports_a_bad_file_and_writes_nothing(tmp_path, capsys):
    bad = tmp_path / "bad.yaml"
    bad.write_text(json.dumps(layout(lambda d: d["objects"][3].pop("size"))))
    assert main(["layout", str(bad), "--output", str(tmp_path / "out.json")]) == 2
    assert "missing field 'size'" in capsys.readouterr().err and not (tmp_path / "out.json").exists()
    # a YAML syntax error in one line, with where the parser stopped
    bad.write_text("robot_x: 0.3\nobjects: [\n")
    assert main(["layout", str(bad), "--output", str(tmp_path / "out.json")]) == 2
    err = capsys.readouterr().err
    assert err.startswith(f"error: {bad}: not valid YAML at line 3, column 1: ") and err.count("\n") == 1
    assert not (tmp_path / "out.json").exists()


def test_a_number_yaml_reads_as_text_is_taken():
    """PyYAML (YAML 1.1) reads `-6e-1` as text, its exponent form needing a dot: still the number it spells."""
    data = yaml.safe_load(EXAMPLE.read_text().replace("{id: thermos, at: workbench, dx: -0.6}",
                                                      "{id: thermos, at: workbench, dx: -6e-1}"))
    assert data["items"][0]["dx"] == "-6e-1"
    assert environment_from_layout(data) == environment_from_layout(yaml.safe_load(EXAMPLE.read_text()))


def test_an_item_inside_a_container_may_be_wider_than_it():
    """A liquid stands inside its container, centred, whatever its drawn width (the catalog's tea, 8 cm, in a 7.5 cm
    cup): the offset and width checks are for items standing on something."""
    data = {"furniture": {"obj02": 0.0}, "items": [{"id": "obj14", "at": "obj02"}, {"id": "obj31", "at": "obj14"}]}
    env = environment_from_layout(data)
    assert env["state"]["objects"]["obj31"]["support"] == "obj14"


def test_the_teach_page_lists_every_category_and_flag_a_layout_takes():
    import re

    from taskseq.sim.objects import BINARY_ATTRIBUTES, CATEGORIES

    page = (Path(__file__).resolve().parents[1] / "docs" / "teach.md").read_text()
    said = page.split("Categories are the simulator's:")[1].split("They give the world")[0]
    assert sorted(re.findall(r"`(\w+)`", said)) == sorted(CATEGORIES - {"floor"})  # the floor comes with every room
    said = page.split("The flags\nare the binary attributes:")[1].split("A liquid goes")[0]
    assert re.findall(r"`(\w+)`", said) == [*BINARY_ATTRIBUTES, "levels"]  # the last: the field levels go in
