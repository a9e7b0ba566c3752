"""`taskseq serve` over HTTP: the demonstrate and assist flows, every bad input refused with nothing written,
separate sessions, whole records under concurrent appends and load, and a stop that loses no saved record."""

from __future__ import annotations

import html
import itertools
import json
import re
import signal
import subprocess
import sys
import threading
from pathlib import Path

import numpy as np
import pytest
from werkzeug.serving import make_server

from taskseq.cli import main
from taskseq.learn.estimator import StepScorer
from taskseq.learn.mrf import StepMRF
from taskseq.serve.app import corrections_text, create_app
from taskseq.serve.environments import world_environment
from taskseq.serve.load import Client, LoadResult, run_load, scripted_tasks
from taskseq.serve.rules import preconditions
from taskseq.serve.scene import top_view
from taskseq.serve.writer import RecordWriter, person_record
from taskseq.sim.demonstrator import demonstrate
from taskseq.sim.primitives import ALL_PRIMITIVES, ARITY, Action, PreconditionError, execute
from taskseq.sim.safety import RULES, violations
from taskseq.sim.tasks import Task

POUR = Task("pour", ("obj27",))  # env01: the water in its bottle, on the kitchen table


def message(resp) -> str:
    """The page's message as a person reads it (the HTML escapes undone)."""
    found = re.search(r'id="message">([^<]*)<', resp.get_data(as_text=True))
    return html.unescape(found.group(1)) if found else ""


def step_form(n: int, action: Action) -> dict[str, str]:
    args = list(action.args) + [""] * (2 - len(action.args))
    return {"n": str(n), "primitive": action.primitive, "a1": args[0], "a2": args[1]}


def files_under(root: Path) -> list[str]:
    return sorted(str(p.relative_to(root)) for p in root.rglob("*") if p.is_file())


@pytest.fixture
def data(tmp_path) -> Path:
    return tmp_path / "data"


@pytest.fixture
def zero_model(tmp_path) -> Path:
    """A planner whose scores all tie: its best proposal is the first candidate, never a demonstrated step."""
    path = tmp_path / "zero.npz"
    StepScorer.from_weights("full", np.zeros(StepMRF("full").size_joint_feature)).save(path)
    return path


@pytest.fixture
def client(data, zero_model):
    return create_app(data, zero_model).test_client()


def start(client, task: Task = POUR, mode: str = "demonstrate", participant: str = "", env_id: str = "env01"):
    assert client.post("/environment", data={"source": "world", "seed": "0", "env_id": env_id}).status_code == 303
    args = {"arg1": task.args[0], "arg2": task.args[1] if len(task.args) > 1 else ""}
    return client.post("/task", data={"task": task.name, **args, "mode": mode, "participant": participant})


def demonstrated(task: Task = POUR, env_id: str = "env01") -> list[Action]:
    return demonstrate(world_environment(0, env_id).state, task)[0]


def test_a_demonstration_is_refused_an_infeasible_step_and_saved_as_a_log_record(client, data, capsys):
    assert start(client, participant="p07").headers["Location"] == "/demonstrate"
    page = client.get("/demonstrate").get_data(as_text=True)
    assert "water_bottle" in page and "<svg" in page and "the goal does not hold yet" in page
    refused = client.post("/step", data=step_form(0, Action("grasp", ("obj20",))))
    assert refused.status_code == 409
    assert "grasp(water_bottle) is refused" in message(refused) and "water_bottle is" in message(refused)
    assert "from the robot" in message(refused)
    assert not (data / "people").exists()
    early = client.post("/step", data=step_form(0, Action("done")))
    assert "no step has been taken yet" in message(early)
    actions = demonstrated()
    for k, action in enumerate(actions):
        assert client.post("/step", data=step_form(k, action)).status_code == 303
    assert "the goal holds" in client.get("/demonstrate").get_data(as_text=True)
    assert client.post("/step", data=step_form(len(actions), Action("done"))).headers["Location"] == "/finished"
    assert "people/w0-env01.jsonl" in client.get("/finished").get_data(as_text=True)
    [line] = (data / "people" / "w0-env01.jsonl").read_text().splitlines()
    record = json.loads(line)
    assert record["participant"] == "p07" and "corrected" not in record
    assert [s["primitive"] for s in record["steps"]] == [a.primitive for a in actions]
    assert main(["replay", str(data / "people")]) == 0
    assert main(["--no-mlflow", "ingest", "--input", str(data / "people"), "--output", str(data.parent / "t")]) == 0
    assert "ingested 1 sequence (" in capsys.readouterr().out


def test_undo_takes_back_the_last_step(client):
    start(client)
    client.post("/step", data=step_form(0, Action("move_close", ("obj20",))))
    assert client.post("/undo", data={"n": "1"}).status_code == 303
    assert "None yet." in client.get("/demonstrate").get_data(as_text=True)
    assert "no step to undo" in message(client.post("/undo", data={"n": "0"}))


@pytest.mark.parametrize("form, expected", [
    ({"primitive": "grasp", "a1": "obj99"}, "unknown object 'obj99'"),
    ({"primitive": "grasp", "a1": "<b>obj20</b>"}, "unknown object '<b>obj20</b>'"),
    ({"primitive": "teleport", "a1": "obj20"}, "unknown primitive 'teleport'"),
    ({"primitive": "place_above", "a1": "obj20"}, "place_above takes two objects, got one object"),
    ({"primitive": "grasp", "a1": "obj20", "a2": "obj14"}, "grasp takes one object, got two objects"),
    ({"primitive": "hold_above", "a1": "obj20", "a2": "obj20"}, "needs two different objects"),
    ({"primitive": "grasp", "a1": "obj20", "n": "3"}, "this page was out of date"),
    ({"primitive": "grasp", "a1": "obj20", "n": "x"}, "this page was out of date"),
    ({"choice": "0"}, "no proposals to choose from"),
])
def test_a_bad_step_is_refused_with_a_message_and_changes_nothing(client, data, form, expected):
    start(client)
    resp = client.post("/step", data={"n": "0", "a1": "", "a2": "", **form})
    assert resp.status_code in (400, 409)
    assert expected in message(resp)
    assert "None yet." in client.get("/demonstrate").get_data(as_text=True)
    assert not (data / "people").exists()


# In env01 of world 0, for each safety rule: the steps leading to a step that breaks it, that step, and what the
# refusal must say besides the rule itself (in names: the water in its bottle, the magazine with a chopstick and
# crumpled paper on it, the teacup on the kitchen shelf)
UNSAFE = {
    "liquid_grasped": (["move_close(obj20)"], "grasp(obj27)",
                       ["grasp(water) is refused", "water is a liquid", "grasp water_bottle"]),
    "grasp_with_load": (["move_close(obj40)"], "grasp(obj40)",
                        ["grasp(magazine) is refused", "chopstick and crumpled_paper rest on magazine"]),
    "over_shelf": (["move_close(obj20)", "grasp(obj20)", "move_close(obj17)", "hold_above(obj20,obj17)"],
                   "follow_traj_pour(obj20,obj17)",
                   ["follow_traj_pour(water_bottle, teacup) is refused", "teacup is on kitchen_shelf"]),
}


@pytest.mark.parametrize("rule", sorted(RULES))  # a rule added to the simulator without a case here fails
def test_a_step_that_breaks_a_safety_rule_is_refused_naming_the_rule_and_the_objects(client, data, rule):
    before, unsafe, said = UNSAFE[rule]
    start(client)
    for k, text in enumerate(before):
        assert client.post("/step", data=step_form(k, Action.parse(text))).status_code == 303
    refused = client.post("/step", data=step_form(len(before), Action.parse(unsafe)))
    assert refused.status_code == 409
    text = message(refused)
    assert f"breaks the safety rule \u201c{RULES[rule]}\u201d" in text and text.endswith("nothing was done")
    assert all(s in text for s in said), text
    assert not re.search(r"\bobj\d+\b|\bNone\b", text), text  # names, never ids or Python's None
    # the refused step's row keeps the objects chosen in it (those its lists offer), and no other row chooses any
    action, html = Action.parse(unsafe), refused.get_data(as_text=True)
    row = re.search(rf'id="step-{action.primitive}".*?</form>', html, re.S).group(0)
    offered = set(re.findall(r'<option value="(\w+)"', row))
    kept = [a for a in action.args if a in offered]
    assert re.findall(r'<option value="(\w+)" selected>', html) == kept
    assert kept or rule == "liquid_grasped"  # only the liquid is offered by no list
    page = client.get("/demonstrate").get_data(as_text=True)
    assert f'name="n" value="{len(before)}"' in page  # nothing was done: the steps are those before
    assert " selected>" not in page  # a fresh page chooses nothing
    assert not (data / "people").exists()


def test_a_liquid_carried_out_of_its_container_is_never_saved_as_pouring(client, data):
    """The reported case: grasp the water itself, hold it above the cup, release it, done."""
    start(client, Task("pour_to", ("obj27", "obj14")))
    assert client.post("/step", data=step_form(0, Action("move_close", ("obj20",)))).status_code == 303
    for text in ("grasp(obj27)", "hold_above(obj27,obj14)", "release(obj27)", "done"):
        assert client.post("/step", data=step_form(1, Action.parse(text))).status_code == 409, text
    assert not (data / "people").exists()


def test_the_writer_refuses_a_record_with_an_unsafe_step_naming_it(tmp_path):
    """A record that replays and reaches its goal, but only by carrying the water out of its bottle: ingest would
    accept it, the people's log must not."""
    env = world_environment(0, "env01")
    actions = [Action.parse(t) for t in ("move_close(obj20)", "grasp(obj27)", "hold_above(obj27,obj14)",
                                         "release(obj27)")]
    record = person_record(env, Task("pour_to", ("obj27", "obj14")), actions)
    with pytest.raises(ValueError, match=r"steps\[1\]: grasp\(water\): it breaks the safety rule .a liquid is "
                                         r"handled only through its container"):
        RecordWriter(tmp_path / "people").append(record)
    assert not (tmp_path / "people").exists()


def test_the_page_states_the_rules_the_simulator_applies(client):
    start(client)
    rules = html.unescape(client.get("/demonstrate").get_data(as_text=True).split('id="rules"')[1])
    for words in RULES.values():
        assert f"<li>{words}</li>" in rules
    assert "<code>grasp(a1)</code>: gripper empty, movable, within reach</li>" in rules
    assert "<code>follow_traj_pour(a1, a2)</code>: held, held above, liquid inside, container</li>" in rules


def test_each_object_of_the_picture_is_a_group_a_click_can_name_titled_with_its_name(client):
    """The hooks of the page's script: one group per drawn object with its id and name, each liquid's name in its
    container's label a shape of its own, and what each step list offers in words; the script is the server's."""
    start(client)
    text = client.get("/demonstrate").get_data(as_text=True)
    svg = text.split('<svg id="scene"')[1].split("</svg>")[0]
    group = r'<g class="object" data-object="(\w+)" data-name="(\w+)" data-kind="\w+"><title>([^<]*)</title>'
    groups = re.findall(group, svg)
    state = world_environment(0, "env01").state
    liquids = {o for o in state.specs if state.specs[o].has("liquid")}
    assert sorted(o for o, _, _ in groups) == sorted(set(state.specs) - liquids - {"obj01"})  # no floor
    assert all(name == state.specs[o].name and title.startswith(name) for o, name, title in groups)
    assert ("obj20", "water_bottle", "water_bottle (water)") in groups
    kinds = dict(re.findall(r'data-object="(\w+)" data-name="\w+" data-kind="(\w+)"', svg))
    assert kinds["obj02"] == "furniture" and kinds["obj10"] == "bin" and kinds["obj20"] != "furniture"
    assert sorted(re.findall(r'<tspan class="object" data-object="(\w+)" data-name="\w+" data-liquid>', svg)) == \
        sorted(liquids)
    assert '<select name="a1" aria-label="grasp a1" data-offers="movable things, never a liquid">' in text
    script = client.get("/static/pick.js")
    assert script.status_code == 200 and script.mimetype.endswith("javascript")


def test_a_moved_name_is_drawn_with_a_line_to_its_shape_that_is_never_clicked_nor_over_a_name(client):
    """The lines of `Shape.leader` in the picture: one per moved name, above the shapes, out of the way of clicks,
    masked by every item's name (each name is cut out of the mask), so that no line covers a name."""
    start(client)
    svg = client.get("/demonstrate").get_data(as_text=True).split('<svg id="scene"')[1].split("</svg>")[0]
    led = {s.id: s.leader for s in top_view(world_environment(0, "env01").state).shapes if s.leader}
    assert set(led) == {"obj17", "obj43"}  # the teacup's name, over the tablespoon; the crumpled paper's
    assert '<g id="leaders" mask="url(#leader-mask)" pointer-events="none"' in svg
    lines = re.findall(r'data-leader-of="(\w+)"><line x1="([^"]+)" y1="([^"]+)" x2="([^"]+)" y2="([^"]+)"', svg)
    assert {o: tuple(float(v) for v in xy) for o, *xy in lines} == led
    assert svg.index('id="leaders"') > svg.rindex('<g class="object"')  # above every shape
    names = re.findall(r'<text id="(name-\d+)"', svg)
    cut = re.findall(r'<use href="#(name-\d+)" class="knockout"/>', svg.split('<mask id="leader-mask"')[1])
    assert cut and set(cut) <= set(names) and len(cut) == sum(1 for s in top_view(
        world_environment(0, "env01").state).shapes if s.kind in ("vessel", "item"))


def test_the_checks_the_page_lists_are_the_checks_the_simulator_makes():
    """Every check that refuses a step in some states of env01 is among its primitive's listed checks, and every
    listed check refuses some step there: the list is read from the simulator's code, and matches what it does."""
    initial = world_environment(0, "env01").state
    states = []
    for task in (POUR, Task("stir", ("obj32",))):  # states holding a bottle, and a stirrer over the coffee
        state = initial
        for action in demonstrated(task):
            states.append(state)
            state = execute(state, action)
        states.append(state)
    holding = next(s for s in states if s.held == "obj20")
    states.append(execute(holding, Action("hold_above", ("obj20", "obj02"))))  # the bottle over the table itself
    ids = sorted(state.specs)
    seen: dict[str, set[str]] = {p: set() for p in ALL_PRIMITIVES}
    for s in states:
        for p in ALL_PRIMITIVES:
            for args in itertools.permutations(ids, ARITY[p]):
                try:
                    execute(s, Action(p, args))
                except PreconditionError as err:
                    seen[p].add(err.check)
    assert seen == {p: set(c) for p, c in preconditions().items()}


@pytest.mark.parametrize("form, expected", [
    ({"task": "pour", "arg1": "obj20"}, "task pour(water_bottle): water_bottle (obj20) is not a liquid"),
    ({"task": "pour", "arg1": "obj99"}, "unknown object 'obj99'"),
    ({"task": "pour", "arg1": "obj27", "arg2": "obj14"},
     "pour takes one object, got two objects (water, cup); set the second object to (none)"),
    ({"task": "pick_and_place", "arg1": "obj40"}, "pick_and_place takes two objects, got one object (magazine)"),
    ({"task": "fly", "arg1": "obj27"}, "unknown task 'fly'"),
    ({"task": "pick_and_place", "arg1": "obj43", "arg2": "obj40"}, "already holds"),
    ({"task": "pour", "arg1": "obj27", "mode": "watch"}, "unknown mode 'watch'"),
    ({"task": "pour", "arg1": "obj27", "participant": "../../x"}, "participant id '../../x'"),
    ({"task": "pour", "arg1": "obj27", "participant": "a b"}, "participant id 'a b'"),
])
def test_a_bad_task_is_refused_with_a_message(client, data, form, expected):
    client.post("/environment", data={"source": "world", "seed": "0", "env_id": "env01"})
    resp = client.post("/task", data={"arg2": "", "mode": "demonstrate", **form})
    assert resp.status_code == 400
    assert expected in message(resp)
    assert not (data / "people").exists()


def environment_file(edit=None) -> str:
    state = world_environment(0, "env01").state
    from taskseq.demonstrations.records import spec_to_dict, state_to_dict

    env = {"objects": [spec_to_dict(s) for s in state.specs.values()], "state": state_to_dict(state)}
    if edit:
        edit(env)
    return json.dumps(env)


def upload(client, text: str, name: str = "kitchen.json"):
    import io

    return client.post("/environment", data={"source": "upload", "file": (io.BytesIO(text.encode()), name)},
                       content_type="multipart/form-data")


def _drop_size(env):
    del env["objects"][1]["size"]


def _loop(env):
    env["state"]["objects"]["obj02"]["support"] = "obj20"


@pytest.mark.parametrize("text, expected", [
    ("{not json", "kitchen.json: cannot read the environment"),
    (environment_file(_drop_size), "objects[1]: 'size' is a required property"),
    (environment_file(lambda e: e["objects"][2].update(category="sofa")), "objects[2].category"),
    (environment_file(lambda e: e["state"]["objects"].pop("obj27")), "state.objects.obj27"),
    (environment_file(_loop), "form a loop"),
    (environment_file(lambda e: e["state"]["objects"]["obj02"].update(support="obj02")),
     "state.objects.obj02.support: the objects it rests on form a loop through obj02"),
    (environment_file(lambda e: e["state"]["objects"]["obj02"].update(support="ghost")),
     "state.objects.obj02.support: unknown object 'ghost'"),  # the message whole, its closing quote too
    (environment_file(lambda e: e["objects"].append(dict(e["objects"][0]))), "is listed twice"),
])
def test_a_bad_environment_file_is_refused_naming_the_field(client, data, text, expected):
    resp = upload(client, text)
    assert resp.status_code == 400
    assert expected in message(resp)
    assert not data.exists()


@pytest.mark.parametrize("form, expected", [
    ({"source": "world", "seed": "-1", "env_id": "env01"}, "world seed must be a whole number"),
    ({"source": "world", "seed": "0", "env_id": "env99"}, "unknown environment 'env99'"),
    ({"source": "named", "name": "../../etc/passwd"}, "no environment file"),
    ({"source": "disk"}, "unknown environment source"),
])
def test_a_bad_environment_choice_is_refused(client, form, expected):
    resp = client.post("/environment", data=form)
    assert resp.status_code == 400 and expected in message(resp)


def test_names_from_an_environment_file_are_shown_as_text_and_no_file_leaves_the_data_folder(client, data, tmp_path):
    def rename(env):
        next(o for o in env["objects"] if o["id"] == "obj20")["name"] = "<script>alert(1)</script>"

    assert upload(client, environment_file(rename), name="../../evil.json").status_code == 303
    page = client.get("/task")
    text = page.get_data(as_text=True)
    assert "&lt;script&gt;alert(1)&lt;/script&gt;" in text and "<script>" not in text
    assert sorted(re.findall(r"<script[^>]*>", text)) == [  # the server's own, nothing inline
        '<script src="/leave.js">', '<script src="/static/pick.js" defer>']
    policy = page.headers["Content-Security-Policy"]
    assert "script-src 'self';" in policy and "unsafe-inline" not in policy.split("script-src")[1].split(";")[0]
    client.post("/task", data={"task": "pour", "arg1": "obj27", "arg2": "", "mode": "demonstrate",
                               "participant": "p1"})
    actions = demonstrated()
    for k, action in enumerate(actions + [Action("done")]):
        client.post("/step", data=step_form(k, action))
    assert [p for p in files_under(tmp_path) if not p.endswith("zero.npz")] == [
        "data/people/.lock", next(p for p in files_under(tmp_path) if p.startswith("data/people/evil-"))]
    assert main(["replay", str(data / "people")]) == 0


def test_the_task_form_lists_each_object_by_name_and_its_id_only_where_they_differ(client):
    def rename(env):
        next(o for o in env["objects"] if o["id"] == "obj20")["name"] = "obj20"  # a file whose ids are its names

    assert upload(client, environment_file(rename), name="same.json").status_code == 303
    text = client.get("/task").get_data(as_text=True)
    assert 'data-name="obj20">obj20</option>' in text and "obj20 (obj20)" not in text
    assert 'data-name="water">water (obj27)</option>' in text


def test_named_environment_files_come_from_the_data_folder(client, data):
    (data / "environments").mkdir(parents=True)
    (data / "environments" / "flat.json").write_text(environment_file())
    assert "flat.json" in client.get("/").get_data(as_text=True)
    assert client.post("/environment", data={"source": "named", "name": "flat.json"}).status_code == 303
    assert "flat.json" in client.get("/task").get_data(as_text=True)


def test_two_browsers_on_one_environment_keep_their_own_steps(data, zero_model):
    app = create_app(data, zero_model)
    a, b = app.test_client(), app.test_client()
    pick = Task("pick_and_place", ("obj40", "obj08"))
    start(a)
    start(b, pick)
    seq_a, seq_b = demonstrated(), demonstrated(pick)
    for k in range(max(len(seq_a), len(seq_b)) + 1):
        for c, seq in ((a, seq_a), (b, seq_b)):
            if k <= len(seq):
                resp = c.post("/step", data=step_form(k, seq[k] if k < len(seq) else Action("done")))
                assert resp.status_code == 303, message(resp)
    records = [json.loads(line) for line in (data / "people" / "w0-env01.jsonl").read_text().splitlines()]
    steps = {r["task"]["name"]: [s["primitive"] for s in r["steps"]] for r in records}
    assert steps == {"pour": [x.primitive for x in seq_a], "pick_and_place": [x.primitive for x in seq_b]}


def test_assist_records_the_steps_where_the_person_overrode_the_planner(client, data):
    start(client, mode="assist")
    page = client.get("/assist").get_data(as_text=True)
    assert page.count('name="choice"') == 3 and "score" in page
    assert "no proposal number" in message(client.post("/step", data={"n": "0", "choice": "7"}))
    actions = demonstrated()
    for k, action in enumerate(actions + [Action("done")]):
        assert client.post("/step", data=step_form(k, action)).status_code == 303
    record = json.loads((data / "people" / "w0-env01.jsonl").read_text())
    # the tied planner always proposes move_close of the first object first, which the person never takes
    assert record["corrected"] == list(range(len(actions) + 1))
    saved = client.get("/finished").get_data(as_text=True)  # the steps as the page lists them, from 1, then done
    steps = ", ".join(str(k) for k in range(1, len(actions) + 1))
    assert f"You corrected the planner at steps {steps} and at done." in saved


def test_the_saved_page_counts_corrections_as_its_list_of_steps_does():
    assert corrections_text([0, 2], 4) == "at steps 1, 3"
    assert corrections_text([1], 4) == "at step 2"
    assert corrections_text([4], 4) == "at done"
    assert corrections_text([3, 4], 4) == "at step 4 and at done"


def test_assist_accepting_a_proposal_is_no_correction(client, data):
    start(client, mode="assist")
    assert client.post("/step", data={"n": "0", "choice": "0"}).status_code == 303  # take the planner's best
    first = client.get("/assist").get_data(as_text=True)
    assert "(your correction)" not in first
    client.post("/undo", data={"n": "1"})
    actions = demonstrated()
    for k, action in enumerate(actions + [Action("done")]):
        client.post("/step", data=step_form(k, action))
    record = json.loads((data / "people" / "w0-env01.jsonl").read_text())
    assert record["corrected"] == list(range(len(actions) + 1))


def test_assist_ranks_with_the_policy_the_model_file_records_and_proposes_only_steps_that_run(data, tmp_path):
    """Whatever policy the model file records, the page proposes only steps it would take; recorded as greedy, the
    weights' best scores among those are the feasible policy's proposals, as `taskseq plan` runs them."""
    weights = np.random.default_rng(0).normal(size=StepMRF("full").size_joint_feature)
    proposals = {}
    for policy in ("greedy", "feasible", "lookahead"):
        path = tmp_path / f"{policy}.npz"
        StepScorer.from_weights("full", weights).save(path, policy=policy)
        client = create_app(data, path).test_client()
        start(client, mode="assist")
        page = client.get("/assist").get_data(as_text=True)
        proposals[policy] = re.findall(r'<td data-step="([^"]*)">', page)
        assert len(proposals[policy]) == page.count('name="choice"') == 3
        initial = world_environment(0, "env01").state
        for text in proposals[policy]:  # it runs, breaks no rule, and done is not due at the start
            assert Action.parse(text).primitive != "done" and not violations(initial, Action.parse(text))
            execute(initial, Action.parse(text))
    assert proposals["greedy"] == proposals["feasible"] and len(proposals["lookahead"]) == 3


def proposal_rows(page: str) -> list[tuple[str, float, str]]:
    """(step, score, why it is here) of each row of the assist table, as a person reads them: a long why's first
    clause is the summary of a <details> holding the rest."""
    rows = re.findall(r'<td data-step="([^"]*)">.*?</td>\s*<td>(-?[0-9.]+)</td><td class="why">(.*?)</td>', page,
                      re.S)
    return [(step, float(score), html.unescape(re.sub(r"<[^>]*>", "", why.replace("</summary>", "; "))))
            for step, score, why in rows]


def test_assist_shows_each_proposal_in_names_with_its_ids_as_a_hint(data, tmp_path):
    """The step a person reads is in the objects' names (`move_close(water_bottle)`); the ids records write follow
    as a hint, and only where they differ from the names."""
    path = tmp_path / "lookahead.npz"
    weights = np.random.default_rng(0).normal(size=StepMRF("full").size_joint_feature)
    StepScorer.from_weights("full", weights).save(path, policy="lookahead")
    client = create_app(data, path).test_client()
    start(client, Task("pour", ("obj27",)), mode="assist")
    page = client.get("/assist").get_data(as_text=True)
    cells = re.findall(r'<td data-step="([^"]*)"><code>([^<]*)</code>( <span class="hint">([^<]*)</span>)?</td>',
                       page)
    assert len(cells) == 3
    state = world_environment(0, "env01").state
    for ids, shown, hint, hinted in cells:
        action = Action.parse(ids)
        assert shown == f"{action.primitive}({', '.join(state.specs[a].name for a in action.args)})"
        assert hinted == (ids if shown != ids else "") and bool(hint) == (shown != ids)
    assert any(hinted for *_, hinted in cells), "env01's objects have names of their own"


def test_assist_says_why_each_proposal_is_where_it_is(data, tmp_path):
    """Under the lookahead a step can stand above a better-scored one: the upper row says it moved up and why,
    the lower one what its imagined plan would break; every row speaks in names, never ids or None."""
    path = tmp_path / "lookahead.npz"
    weights = np.random.default_rng(0).normal(size=StepMRF("full").size_joint_feature)
    StepScorer.from_weights("full", weights).save(path, policy="lookahead")
    client = create_app(data, path).test_client()
    start(client, Task("pour_to", ("obj27", "obj14")), mode="assist")
    client.post("/step", data={"n": "0", "choice": "0"})  # accept the first proposal: here the lookahead reorders
    page = client.get("/assist").get_data(as_text=True)
    rows = proposal_rows(page)
    assert len(rows) == 3
    # the first row's long why shows its first clause; the plan the lookahead imagined is folded under it
    folded = re.search(r'<td class="why"><details><summary>([^<]*)</summary>([^<]*)</details></td>', page)
    assert folded and rows[0][2] == f"{html.unescape(folded[1])}; {html.unescape(folded[2])}"
    assert folded[1].startswith("moved up above ") and "; looking ahead (" in folded[2]
    swapped = [(i, j) for i in range(3) for j in range(i + 1, 3) if rows[i][1] < rows[j][1]]
    assert swapped, "this room and these weights were chosen for a proposal above a better-scored one"
    names = world_environment(0, "env01").state.specs
    for i, j in swapped:
        lower = Action.parse(rows[j][0])
        named_lower = f"{lower.primitive}({', '.join(names[a].name for a in lower.args)})"
        assert f"moved up above {named_lower}" in rows[i][2] and "the lookahead found" in rows[i][2]
        assert rows[j][2].startswith("demoted: its plan would ") and "it breaks the safety rule \u201c" in rows[j][2]
    for _, _, why in rows:
        assert why and not re.search(r"\bobj\d+\b", why) and "None" not in why


def test_assist_names_a_policy_this_version_does_not_plan_with(data, tmp_path):
    path = tmp_path / "odd.npz"
    StepScorer.from_weights("full", np.zeros(StepMRF("full").size_joint_feature)).save(path, policy="cautious")
    client = create_app(data, path).test_client()
    page = client.get(start(client, mode="assist").headers["Location"])
    assert "the planner cannot be loaded" in message(page) and "policy 'cautious'" in message(page)


def test_assist_names_a_missing_model(data):
    client = create_app(data, data / "none.npz").test_client()
    resp = start(client, mode="assist")
    page = client.get(resp.headers["Location"])
    assert "the planner cannot be loaded" in message(page) and "no such model file" in message(page)


def test_concurrent_appends_write_every_record_whole(tmp_path):
    env = world_environment(0, "env01")
    actions = demonstrated()
    writers = [RecordWriter(tmp_path), RecordWriter(tmp_path)]  # two servers on one folder
    ids: list[str] = []

    def work(i: int) -> None:
        for _ in range(5):
            record = person_record(env, POUR, actions, f"p{i}")
            writers[i % 2].append(record)
            ids.append(record["demo_id"])

    threads = [threading.Thread(target=work, args=(i,)) for i in range(6)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    lines = (tmp_path / "w0-env01.jsonl").read_text().splitlines()
    assert sorted(json.loads(line)["demo_id"] for line in lines) == sorted(ids) and len(ids) == 30
    assert sorted(p.name for p in tmp_path.iterdir()) == [".lock", "w0-env01.jsonl"]
    with pytest.raises(ValueError, match="cannot name a log file"):
        writers[0].path_for("../x")


def test_a_record_that_does_not_reach_its_goal_is_never_written(tmp_path):
    record = person_record(world_environment(0, "env01"), POUR, demonstrated()[:-1])
    with pytest.raises(ValueError, match="goal of pour"):
        RecordWriter(tmp_path).append(record)
    assert not (tmp_path / "w0-env01.jsonl").exists()


@pytest.fixture
def server(data, zero_model):
    srv = make_server("127.0.0.1", 0, create_app(data, zero_model), threaded=True)
    thread = threading.Thread(target=srv.serve_forever)
    thread.start()
    yield f"http://127.0.0.1:{srv.port}"
    srv.shutdown()
    thread.join()


def test_a_load_of_concurrent_browsers_loses_no_record_and_leaves_no_partial_file(server, data):
    result = run_load(server, clients=4, rounds=5)
    assert result.errors == []
    assert result.requests >= 300
    on_disk = [json.loads(line)["demo_id"] for f in sorted((data / "people").glob("*.jsonl"))
               for line in f.read_text().splitlines()]
    assert sorted(on_disk) == sorted(result.saved) and len(on_disk) == 20
    assert sorted(p.name for p in (data / "people").iterdir()) == [".lock", "w0-env01.jsonl", "w0-env02.jsonl"]
    assert main(["replay", str(data / "people")]) == 0


@pytest.mark.parametrize("signum", [signal.SIGTERM, signal.SIGINT])
def test_a_stopped_server_keeps_every_saved_record_whole(data, zero_model, signum):
    proc = subprocess.Popen([sys.executable, "-m", "taskseq.cli", "serve", "--port", "0", "--data", str(data),
                             "--model", str(zero_model)], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        url = re.search(r"http://\S+/", proc.stdout.readline()).group(0).rstrip("/")
        result = LoadResult()
        client = Client(url, result, threading.Lock())
        for task, actions in scripted_tasks(0, "env01", 2):
            client.demonstrate(0, "env01", task, actions)
        assert result.errors == [] and len(result.saved) == 2
    finally:
        proc.send_signal(signum)
        _, err = proc.communicate()
    assert proc.returncode == 0 and "stopped; every demonstration it saved is whole" in err
    lines = (data / "people" / "w0-env01.jsonl").read_text().splitlines()
    assert [json.loads(line)["demo_id"] for line in lines] == result.saved


def test_starting_another_task_with_unsaved_steps_asks_first_and_changes_nothing_until_confirmed(client, data):
    """Without any script: the new task is checked, then a page lists the steps that would be lost; going back
    keeps them, confirming drops them and starts the new task. A finished or empty task asks nothing."""
    start(client)
    for k, action in enumerate(demonstrated()[:2]):
        client.post("/step", data=step_form(k, action))
    other = {"task": "throw_away", "arg1": "obj43", "arg2": "", "mode": "demonstrate", "participant": ""}
    asked = client.post("/task", data=other)
    page = asked.get_data(as_text=True)
    text = html.unescape(re.sub(r"<[^>]+>", "", page))  # as a person reads it
    assert asked.status_code == 409 and "pour(water) is not finished: its 2 steps so far are not saved" in text
    assert "move_close(water_bottle)" in text and "go on to throw_away(crumpled_paper)" in text
    assert 'href="/demonstrate"' in page
    page = client.get("/demonstrate").get_data(as_text=True)
    assert page.count("<li>move_close(water_bottle)") + page.count("<li>grasp(water_bottle)") == 2  # both kept
    assert 'data-unsaved="2"' in page
    bad = client.post("/task", data={**other, "arg1": "obj99"})  # a bad task is refused before anything is asked
    assert bad.status_code == 400 and "unknown object 'obj99'" in message(bad)
    assert client.post("/task", data={**other, "discard": "yes"}).headers["Location"] == "/demonstrate"
    page = client.get("/demonstrate").get_data(as_text=True)
    assert "throw_away(obj43)" in page and "None yet." in page and "data-unsaved" not in page
    assert client.post("/task", data=other).status_code == 303  # nothing unsaved: nothing to ask
    assert not (data / "people").exists()


def test_choosing_another_environment_with_unsaved_steps_asks_first(client):
    start(client)
    assert 'id="under-way"' not in client.get("/").get_data(as_text=True)  # no step yet: nothing under way
    client.post("/step", data=step_form(0, demonstrated()[0]))
    first = client.get("/").get_data(as_text=True)  # the first page says what is under way, with a link back
    assert '<a href="/demonstrate">pour(water), 1 step</a>' in first.split('id="under-way"')[1].split("</p>")[0]
    env02 = {"source": "world", "seed": "0", "env_id": "env02"}
    asked = client.post("/environment", data=env02)
    assert asked.status_code == 409 and "its 1 step so far is not saved" in html.unescape(asked.get_data(as_text=True))
    assert "env01" in client.get("/task").get_data(as_text=True).split("</header>")[0]  # still in env01
    assert client.post("/environment", data={"source": "pending", "discard": "yes"}).headers["Location"] == "/task"
    assert "env02" in client.get("/task").get_data(as_text=True).split("</header>")[0]
    refused = client.post("/environment", data={"source": "pending", "discard": "yes"})  # used once
    assert refused.status_code == 400 and "no environment is waiting" in message(refused)


def test_a_confirmation_for_an_environment_another_tab_replaced_changes_nothing(client):
    """Two tabs with unsaved steps each choose an environment: the page asking about env02 must not switch to
    env03, chosen since in the other tab (one environment waits per browser)."""
    start(client)
    client.post("/step", data=step_form(0, demonstrated()[0]))
    tab_a = client.post("/environment", data={"source": "world", "seed": "0", "env_id": "env02"})
    asked = dict(re.findall(r'name="(source|pending)" value="([^"]*)"', tab_a.get_data(as_text=True)))
    assert asked == {"source": "pending", "pending": "w0-env02"}
    client.post("/environment", data={"source": "world", "seed": "0", "env_id": "env03"})  # tab B
    refused = client.post("/environment", data={**asked, "discard": "yes"})
    assert refused.status_code == 409 and message(refused) == (
        "this page asked about another environment than the one now waiting (env03 of world 0, chosen since in this "
        "browser); nothing was changed: choose again")
    assert "env01" in client.get("/task").get_data(as_text=True).split("</header>")[0]  # still in env01
    assert client.get("/demonstrate").status_code == 200  # and the task with its step still under way


def drawn_for(page: str) -> dict[str, str]:
    """The activity and step count a page's forms carry: what a form of that page, kept open in a tab, posts."""
    activity = re.search(r'name="activity" value="([^"]*)"', page).group(1)
    n = re.search(r'name="activity" value="[^"]*"><input type="hidden" name="n" value="([^"]*)"', page).group(1)
    return {"activity": activity, "n": n}


THROW = Task("throw_away", ("obj43",))  # env01: the crumpled paper


def test_every_form_acting_on_the_task_under_way_names_the_activity_it_was_drawn_for(client):
    """Each step row, done, undo and the proposals of assist, and the button that drops unsaved steps."""
    for mode in ("demonstrate", "assist"):
        start(client, mode=mode)
        client.post("/step", data=step_form(0, demonstrated()[0]))
        page = client.get(f"/{mode}").get_data(as_text=True)
        forms = re.findall(r"<form [^>]*>.*?</form>", page, re.S)
        ids = {re.search(r'id="([^"]+)"', f).group(1) for f in forms}
        assert {"undo-form", "step-grasp", "step-done"} <= ids and ("proposals" in ids) == (mode == "assist")
        assert all(re.search(r'name="activity" value="\d+"><input type="hidden" name="n" value="1"', f) for f in forms)
        asked = client.post("/task", data={"task": "throw_away", "arg1": "obj43", "arg2": "", "mode": mode})
        assert drawn_for(asked.get_data(as_text=True)) == drawn_for(page)
        client.post("/task", data={"task": "throw_away", "arg1": "obj43", "arg2": "", "mode": mode, "discard": "yes",
                                   **drawn_for(page)})
        assert drawn_for(client.get(f"/{mode}").get_data(as_text=True))["activity"] != drawn_for(page)["activity"]


def test_a_step_from_a_page_of_another_task_is_refused_even_at_the_same_step_count(client, data):
    """Two tabs of one browser share its session: a page of throw_away(crumpled_paper) left open at step 0 while
    the other tab starts pour(water), also at step 0, must not add its step to pour(water)."""
    start(client, THROW)
    tab_a = drawn_for(client.get("/demonstrate").get_data(as_text=True))
    assert client.post("/task", data={"task": "pour", "arg1": "obj27", "arg2": "",  # tab B: nothing to ask
                                      "mode": "demonstrate"}).status_code == 303
    for path, form in (("/step", step_form(0, Action("move_close", ("obj43",)))),
                       ("/step", step_form(0, Action("done"))), ("/undo", {})):
        refused = client.post(path, data={**form, **tab_a})
        assert refused.status_code == 409, path
        assert message(refused) == ("this page was for a task no longer under way: since it was drawn, pour(water) "
                                    "was started in this browser (0 steps now); nothing was done")
    page = client.get("/demonstrate").get_data(as_text=True)
    assert "<code>pour(water)</code>" in page and "None yet." in page  # nothing was added
    tab_b = drawn_for(page)
    assert client.post("/step", data={**step_form(0, demonstrated()[0]), **tab_b}).status_code == 303
    stale = client.post("/step", data={**step_form(0, demonstrated()[1]), **tab_b})  # the same task, a step behind
    assert stale.status_code == 409
    assert message(stale) == "this page was out of date (the demonstration has 1 step now); nothing was done"
    assert not (data / "people").exists()


def test_a_page_of_steps_another_tab_dropped_for_another_task_says_the_task_changed(client):
    start(client)
    for k, action in enumerate(demonstrated()[:2]):
        client.post("/step", data=step_form(k, action))
    tab_a = drawn_for(client.get("/demonstrate").get_data(as_text=True))
    other = {"task": "throw_away", "arg1": "obj43", "arg2": "", "mode": "demonstrate"}
    asked = client.post("/task", data=other)  # tab B: asked first, then drops the two steps
    assert client.post("/task", data={**other, "discard": "yes",
                                      **drawn_for(asked.get_data(as_text=True))}).status_code == 303
    refused = client.post("/step", data={**step_form(2, demonstrated()[2]), **tab_a})
    assert refused.status_code == 409 and "out of date" not in message(refused)
    assert message(refused) == ("this page was for a task no longer under way: since it was drawn, "
                                "throw_away(crumpled_paper) was started in this browser (0 steps now); "
                                "nothing was done")
    assert "None yet." in refused.get_data(as_text=True)


def test_dropping_steps_from_a_page_another_tab_has_outdated_asks_again(client):
    """The page that asks before steps are dropped lists them; its button drops those, not the steps or the task
    another tab has taken or started since: the server asks again, listing what is under way now."""
    start(client)
    actions = demonstrated()
    client.post("/step", data=step_form(0, actions[0]))
    other = {"task": "throw_away", "arg1": "obj43", "arg2": "", "mode": "demonstrate"}
    tab_a = drawn_for(client.post("/task", data=other).get_data(as_text=True))  # asked about 1 step
    client.post("/step", data=step_form(1, actions[1]))  # tab B takes another
    again = client.post("/task", data={**other, "discard": "yes", **tab_a})
    text = html.unescape(re.sub(r"<[^>]+>", "", again.get_data(as_text=True)))
    assert again.status_code == 409 and "its 2 steps so far are not saved" in text
    assert message(again) == ("this page was out of date (the demonstration has 2 steps now); nothing was dropped: "
                              "drop the steps below, or go back to them")
    assert "<code>pour(water)</code>" in client.get("/demonstrate").get_data(as_text=True)  # kept
    assert client.post("/task", data={**other, "discard": "yes",
                                      **drawn_for(again.get_data(as_text=True))}).status_code == 303
    assert "None yet." in client.get("/demonstrate").get_data(as_text=True)


@pytest.mark.parametrize("option, expected", [
    (["--port", "70000"], "argument --port: expected a port from 0 to 65535, got '70000'"),
    (["--port", "-5"], "argument --port: expected a port from 0 to 65535, got '-5'"),
    (["--top-k", "0"], "argument --top-k: expected a positive whole number, got '0'"),
])
def test_serve_refuses_a_port_or_proposal_count_that_cannot_be(option, expected, capsys):
    """A port past 65535 was taken modulo 65536 (70000 listened on 4464) and a negative one crashed; top-k 0 made
    the assist page say the planner had no step that can run."""
    with pytest.raises(SystemExit) as stop:
        main(["serve", *option])
    assert stop.value.code == 2 and expected in capsys.readouterr().err


@pytest.mark.parametrize("task, expected", [
    (Task("throw_away", ("obj27",)), "water (obj27) is a liquid; throw_away takes the object that holds it"),
    (Task("pick_and_place", ("obj40", "obj40")), "names magazine (obj40) twice"),
    (Task("pour_to", ("obj27", "obj20")),
     "the goal of pour_to(water, water_bottle)  [obj27, obj20] already holds here"),
])
def test_a_task_no_demonstration_can_do_is_refused_with_the_reason(client, data, task, expected):
    resp = start(client, task)
    assert resp.status_code == 400 and expected in message(resp)
    assert not data.exists()


def test_the_pages_name_the_task_the_steps_and_a_refusal_by_the_objects_names(client):
    """Ids (`pour(obj27)`, `move_close(obj20)`) are what the records hold; a person reads names, so the task, the
    steps so far, a refused done and the saved page say `pour(water)`, `move_close(water_bottle)`, with the ids
    only as a hint."""
    start(client)
    actions = demonstrated()
    for k, action in enumerate(actions[:2]):
        client.post("/step", data=step_form(k, action))
    page = client.get("/demonstrate").get_data(as_text=True)
    assert "<b>Task: <code>pour(water)</code></b>" in page and "<title>demonstrate pour(water)" in page
    assert f"<li>{actions[0].primitive}(water_bottle) " in page and f'<span class="hint">{actions[0]}</span>' in page
    refused = client.post("/step", data=step_form(2, Action("done")))
    assert "done is refused: the goal of pour(water) does not hold yet" in message(refused)
    for k, action in enumerate(actions[2:], start=2):
        client.post("/step", data=step_form(k, action))
    client.post("/step", data=step_form(len(actions), Action("done")))
    saved = client.get("/finished").get_data(as_text=True)
    assert "Saved: <code>pour(water)</code>" in saved and f"<li>{actions[0].primitive}(water_bottle)</li>" in saved
    assert "obj20" not in saved.split('id="demo-id"')[0]


def test_two_objects_of_one_name_are_told_apart_and_a_name_of_one_is_shown_alone():
    """`product.told_apart` on env01 with the teacup renamed cup: the two cups (on the kitchen table, on the
    shelf) say where they are, every other object is its name; and the held cup says so."""
    from dataclasses import replace

    from taskseq.product import told_apart

    room = world_environment(0, "env01").state
    state = replace(room, specs={**room.specs, "obj17": replace(room.specs["obj17"], name="cup")})  # a copy
    told = told_apart(state)
    assert (told["obj14"], told["obj17"]) == ("cup on kitchen_table", "cup on kitchen_shelf")
    assert all(told[o] == spec.name for o, spec in state.specs.items() if o not in ("obj14", "obj17"))
    held = execute(execute(state, Action("move_close", ("obj14",))), Action("grasp", ("obj14",)))
    assert told_apart(held)["obj14"] == "cup held"


def test_objects_that_share_a_name_are_told_apart_by_where_they_are_in_every_list(client):
    """Three cups (the mug and the teacup renamed): the task form and the step forms say where each is, as the
    picture shows it, and the id too where two stand on the same furniture; a simulator's refusal says a name once,
    never `kitchen_table (kitchen_table)`."""
    state = world_environment(0, "env01").state
    mug = next(o for o, s in state.specs.items() if s.name == "mug")

    def three_cups(env):
        for o in env["objects"]:
            if o["id"] in (mug, "obj17"):
                o["name"] = "cup"

    assert upload(client, environment_file(three_cups), name="cups.json").status_code == 303
    assert [state.specs[state.support[o][0]].name for o in ("obj14", mug, "obj17")] == [
        "kitchen_table", "kitchen_table", "kitchen_shelf"]
    shown = {"obj14": "cup on kitchen_table [obj14]", mug: f"cup on kitchen_table [{mug}]",
             "obj17": "cup on kitchen_shelf"}
    text = client.get("/task").get_data(as_text=True)
    for o, label in shown.items():  # the id after the label where the label does not say it
        said = label if o in label else f"{label} ({o})"
        assert f'<option value="{o}" data-name="{label}">{said}</option>' in text
    assert 'data-name="water">water (obj27)</option>' in text  # a name no other object has: the name alone
    client.post("/task", data={"task": "pour", "arg1": "obj27", "arg2": "", "mode": "demonstrate"})
    client.post("/step", data=step_form(0, Action("move_close", ("obj20",))))
    page = client.get("/demonstrate").get_data(as_text=True)
    for o, label in shown.items():
        assert f'<option value="{o}">{label}</option>' in page
    client.post("/step", data=step_form(1, Action("move_close", ("obj02",))))
    refused = message(client.post("/step", data=step_form(2, Action("grasp", ("obj02",)))))
    assert "kitchen_table cannot be moved" in refused and "kitchen_table (kitchen_table)" not in refused
    assert client.post("/step", data=step_form(2, Action("move_close", ("obj17",)))).status_code == 303
    assert "<li>move_close(cup on kitchen_shelf) " in client.get("/demonstrate").get_data(as_text=True)


def test_a_task_that_pours_into_what_is_no_container_is_refused_by_name(client, data):
    resp = start(client, Task("pour_to", ("obj27", "obj02")))
    assert resp.status_code == 400
    assert "kitchen_table (obj02) is not a container; pour_to pours into a cup, a bowl or another container" in (
        message(resp))
    assert not data.exists()


def test_the_writers_lock_file_in_the_default_people_folder_is_seen_by_neither_dvc_nor_git():
    """`taskseq serve` saves into data/people by default and takes its lock file there: a file DVC hashed with
    the folder would make the `people` and `train` stages out of date after any demonstration, kept or not."""
    import os
    import shutil

    from dvc.repo import Repo

    from taskseq.serve.writer import LOCK_NAME

    root = Path(__file__).resolve().parents[1]
    lock = root / "data" / "people" / LOCK_NAME
    with Repo(str(root)) as repo:
        assert repo.dvcignore.is_ignored(repo.fs, os.fspath(lock))
        assert not repo.dvcignore.is_ignored(repo.fs, os.fspath(lock.with_name("walkthrough-3b547b83.jsonl")))
    if shutil.which("git") and (root / ".git").exists():
        assert subprocess.run(["git", "check-ignore", "-q", os.fspath(lock)], cwd=root).returncode == 0


def test_a_stir_over_a_liquid_itself_is_refused_saying_where_to_hold(client):
    """The simulator lets the gripper hold a spoon above the tea itself; the stir then finds no liquid in what is
    below, which its own words put as "tea holds no liquid to stir": the page says what is below and where to hold."""
    start(client, Task("stir", ("obj31",)))  # env01: tea, in a mug (obj13)
    steps = [Action("move_close", ("obj34",)), Action("grasp", ("obj34",)), Action("move_close", ("obj13",)),
             Action("hold_above", ("obj34", "obj31"))]
    for k, action in enumerate(steps):
        assert client.post("/step", data=step_form(k, action)).status_code == 303, action
    refused = client.post("/step", data=step_form(len(steps), Action("follow_traj_circle", ("obj34",))))
    assert refused.status_code == 409
    assert message(refused) == ("follow_traj_circle(teaspoon) is refused: teaspoon is held above tea, a liquid "
                                "itself, not a container; hold it above mug, which holds tea (check: liquid below); "
                                "nothing was done")
