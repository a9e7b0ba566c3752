"""`taskseq serve` in a real browser: Debian's headless Chromium driven by Playwright, as a person clicks.

A person demonstrates a task (refused an infeasible step on the way) and the
record ingests; another chooses a task and steps by clicking objects in the
picture; another corrects the learned planner in assist mode; two
browsers at once write two whole records; a step from a tab left on another
task is refused. Screenshots of each page go to the test's temporary folder.
"""

from __future__ import annotations

import json
import threading
from pathlib import Path

import pytest
from playwright.sync_api import Error as PlaywrightError
from playwright.sync_api import sync_playwright
from werkzeug.serving import make_server

from taskseq.cli import main
from taskseq.demonstrations.records import demonstration_record
from taskseq.features.dataset import build_steps
from taskseq.learn.estimator import StepScorer
from taskseq.serve.app import create_app
from taskseq.serve.environments import world_environment
from taskseq.sim.demonstrator import demonstrate
from taskseq.sim.primitives import Action
from taskseq.sim.safety import RULES
from taskseq.sim.scenarios import candidate_scenarios
from taskseq.sim.tasks import Task

CHROMIUM = Path("/usr/bin/chromium")  # Debian's package; .ci/run installs it
ARGS = ["--headless", "--no-sandbox", "--disable-gpu", "--disable-background-networking",
        "--disable-component-update", "--no-first-run"]


@pytest.fixture(scope="module")
def model(tmp_path_factory) -> Path:
    """A planner trained on a third of the scenarios of two other environments: right on some steps of env01."""
    scenarios = [s for s in candidate_scenarios(0) if s.env_id in ("env02", "env03")][::3]
    contexts, _ = build_steps([demonstration_record(s, 0) for s in scenarios])
    path = tmp_path_factory.mktemp("model") / "mrf.npz"
    StepScorer("full", C=3.0, tol=1e-2, max_iter=200).fit(contexts).save(path)
    return path


@pytest.fixture
def server(tmp_path, model):
    data = tmp_path / "data"
    srv = make_server("127.0.0.1", 0, create_app(data, model), threaded=True)
    thread = threading.Thread(target=srv.serve_forever)
    thread.start()
    yield f"http://127.0.0.1:{srv.port}", data
    srv.shutdown()
    thread.join()


@pytest.fixture(scope="module")
def browser():
    with sync_playwright() as p:
        b = p.chromium.launch(executable_path=str(CHROMIUM), args=ARGS)
        yield b
        b.close()


def submit(page, button: str) -> None:
    """Click a form's button and wait until the page it leads to has loaded.

    Reading a page right after a bare click can race its navigation: the new
    document may not be parsed yet, and a count or a list of texts, which do
    not wait, would read an empty page.
    """
    with page.expect_navigation():
        page.click(button)


def choose(page, url: str, task: Task, mode: str, participant: str = "") -> None:
    """Open the first page, pick env01 of world 0 and the task, as a person clicks."""
    page.goto(url + "/")
    page.select_option("#world-form select[name=env_id]", "env01")
    submit(page, "#world-form button")
    page.select_option("#task-form select[name=task]", task.name)
    page.select_option("#task-form select[name=arg1]", task.args[0])
    if len(task.args) > 1:  # a one-object task's second list is left out of the form
        page.select_option("#task-form select[name=arg2]", task.args[1])
    page.fill("#task-form input[name=participant]", participant)
    submit(page, f"#task-form button[value={mode}]")


def click_step(page, action: Action) -> None:
    """Take a step with its primitive's own form: choose each object it offers, then click its button (the held
    object is not chosen: the form names it)."""
    form = f"#step-{action.primitive}"
    for field, obj in zip(("a1", "a2"), action.args, strict=False):
        if page.locator(f"{form} select[name={field}]").count():
            page.select_option(f"{form} select[name={field}]", obj)
        else:
            assert page.locator(f"{form} input[name={field}]").get_attribute("value") == obj
    submit(page, f"{form} button")


def offered(page, primitive: str, field: str) -> list[str]:
    """The names a primitive's form offers for an argument, as the person sees them (not the empty choice the
    page's script puts first)."""
    return page.locator(f"#step-{primitive} select[name={field}] option:not([value=''])").all_inner_texts()


def demonstrated(task: Task) -> list[Action]:
    return demonstrate(world_environment(0, "env01").state, task)[0]


def test_a_person_demonstrates_a_task_in_the_browser_and_the_record_ingests(server, browser, tmp_path, capsys):
    url, data = server
    page = browser.new_page(viewport={"width": 1200, "height": 900})
    failed: list[str] = []  # every file the pages ask for (script, icon) is there; a refused step is a page (409)
    page.on("response", lambda r: failed.append(f"{r.status} {r.url}")
            if r.status >= 400 and r.request.resource_type != "document" else None)
    task = Task("pour", ("obj27",))
    choose(page, url, task, "demonstrate", participant="p01")
    assert page.locator("#scene").is_visible() and "water_bottle" in page.inner_text("#tree")
    click_step(page, Action("grasp", ("obj20",)))  # the bottle is out of reach from where the robot starts
    assert "grasp(water_bottle) is refused" in page.inner_text("#message")
    assert "from the robot" in page.inner_text("#message")
    page.screenshot(path=str(tmp_path / "refused.png"), full_page=True)
    assert not (data / "people").exists()
    actions = demonstrated(task)
    for action in actions:
        click_step(page, action)
        assert page.locator("#message").count() == 0
    assert "the goal holds" in page.inner_text("#goal")
    click_step(page, Action("done"))
    assert "people/w0-env01.jsonl" in page.inner_text("#saved")
    page.screenshot(path=str(tmp_path / "saved.png"), full_page=True)
    assert failed == [] and page.evaluate("document.querySelector('link[rel=icon]').href").endswith("/icon.svg")
    record = json.loads((data / "people" / "w0-env01.jsonl").read_text())
    assert record["participant"] == "p01" and len(record["steps"]) == len(actions)
    assert main(["--no-mlflow", "ingest", "--input", str(data / "people"), "--output", str(tmp_path / "t")]) == 0
    assert "ingested 1 sequence (" in capsys.readouterr().out


def test_a_step_that_breaks_a_safety_rule_is_refused_naming_the_rule(server, browser, tmp_path):
    """The magazine grasped with the chopstick and the paper on it: the page says which rule, in words, with the
    objects' names. (The water is never offered to grasp: tests/test_serve.py posts that one.)"""
    url, data = server
    page = browser.new_page(viewport={"width": 1200, "height": 900})
    choose(page, url, Task("pour_to", ("obj27", "obj14")), "demonstrate")
    assert RULES["grasp_with_load"] in page.inner_text("#rules")  # stated before anyone breaks it
    click_step(page, Action("move_close", ("obj20",)))
    click_step(page, Action("grasp", ("obj40",)))
    said = page.inner_text("#message")
    assert said == ("grasp(magazine) is refused: it breaks the safety rule \u201can object with something on top is "
                    "cleared before it is grasped\u201d: chopstick and crumpled_paper rest on magazine; take them off "
                    "first; nothing was done")
    page.screenshot(path=str(tmp_path / "unsafe.png"), full_page=True)
    assert page.locator("#steps li").count() == 1 and not (data / "people").exists()
    # the refused step's row keeps the magazine, highlighted, and is the row a click fills; no other row chooses
    assert page.locator("#step-grasp select").input_value() == "obj40"
    assert page.locator("#step-move_close select").input_value() == ""
    assert page.locator("tr.picking #step-grasp").count() == 1
    assert page.locator("g.picked[data-object]").evaluate_all("gs => gs.map(g => g.dataset.object)") == ["obj40"]


def test_a_person_corrects_the_planner_in_assist_mode(server, browser, tmp_path):
    url, data = server
    page = browser.new_page(viewport={"width": 1200, "height": 900})
    task = Task("pour", ("obj27",))
    choose(page, url, task, "assist")
    overridden = []
    for k, action in enumerate([*demonstrated(task), Action("done")]):
        cells = page.locator("#proposals td[data-step]")
        proposals = [cells.nth(i).get_attribute("data-step") for i in range(cells.count())]
        assert len(proposals) == 3
        if str(action) in proposals:  # accept the best, or take another proposal
            if proposals.index(str(action)) != 0:
                overridden.append(k)
            submit(page, f"#proposals button[value='{proposals.index(str(action))}']")
        else:  # none of the proposals: choose the step by hand
            overridden.append(k)
            click_step(page, action)
        if k == 0:
            page.screenshot(path=str(tmp_path / "assist.png"), full_page=True)
    assert "people/w0-env01.jsonl" in page.inner_text("#saved")
    record = json.loads((data / "people" / "w0-env01.jsonl").read_text())
    assert record["corrected"] == overridden
    assert main(["replay", str(data / "people")]) == 0


def test_two_browsers_at_once_write_two_whole_records(server, browser):
    url, data = server
    tasks = [Task("pour", ("obj27",)), Task("pick_and_place", ("obj40", "obj08"))]
    pages = [browser.new_context().new_page() for _ in tasks]  # separate contexts: separate cookies
    for page, task, who in zip(pages, tasks, ("a", "b"), strict=True):
        choose(page, url, task, "demonstrate", participant=who)
    plans = [[*demonstrated(t), Action("done")] for t in tasks]
    for k in range(max(len(p) for p in plans)):
        for page, plan in zip(pages, plans, strict=True):
            if k < len(plan):
                click_step(page, plan[k])
    records = [json.loads(line) for line in (data / "people" / "w0-env01.jsonl").read_text().splitlines()]
    got = {r["participant"]: (r["task"]["name"], [s["primitive"] for s in r["steps"]]) for r in records}
    assert got == {w: (t.name, [a.primitive for a in p[:-1]]) for w, t, p in zip("ab", tasks, plans, strict=True)}


def test_a_step_from_a_tab_left_on_another_task_is_refused_naming_the_task_under_way(server, browser):
    """Two tabs of one browser share its session: a step taken in a tab still showing throw_away(crumpled_paper),
    after the other tab started pour(water) (both at step 0), is refused and lands in neither task."""
    url, data = server
    context = browser.new_context(viewport={"width": 1200, "height": 900})
    tab_a, tab_b = context.new_page(), context.new_page()  # one context: one cookie, one session
    choose(tab_a, url, Task("throw_away", ("obj43",)), "demonstrate")
    choose(tab_b, url, Task("pour", ("obj27",)), "demonstrate")
    click_step(tab_a, Action("move_close", ("obj43",)))
    assert tab_a.inner_text("#message") == ("this page was for a task no longer under way: since it was drawn, "
                                            "pour(water) was started in this browser (0 steps now); nothing was done")
    assert tab_a.inner_text("#status code") == "pour(water)" and tab_a.inner_text("#steps") == "None yet."
    tab_b.reload()
    assert tab_b.inner_text("#steps") == "None yet." and not data.joinpath("people").exists()
    context.close()


def test_markup_in_an_uploaded_environment_file_is_shown_as_text_and_never_run(server, browser, tmp_path):
    from taskseq.demonstrations.records import spec_to_dict, state_to_dict

    url, data = server
    state = world_environment(0, "env01").state
    env = {"objects": [spec_to_dict(s) for s in state.specs.values()], "state": state_to_dict(state)}
    next(o for o in env["objects"] if o["id"] == "obj20")["name"] = "<script>alert(1)</script>"
    path = tmp_path / "kitchen.json"
    path.write_text(json.dumps(env))
    page = browser.new_page()
    dialogs: list[str] = []
    page.on("dialog", lambda d: (dialogs.append(d.message), d.dismiss()))
    page.goto(url + "/")
    page.set_input_files("#upload-form input[name=file]", str(path))
    submit(page, "#upload-form button")
    assert "<script>alert(1)</script>" in page.inner_text("#tree")
    assert page.locator("#scene text", has_text="<script>alert(1)</script>").count() == 1
    assert dialogs == []
    del env["objects"][3]["size"]
    path.write_text(json.dumps(env))
    page.goto(url + "/")
    page.set_input_files("#upload-form input[name=file]", str(path))
    submit(page, "#upload-form button")
    assert page.inner_text("#message") == "kitchen.json:1: objects[3]: 'size' is a required property"
    assert not data.exists()


def test_each_primitive_offers_only_the_objects_its_checks_allow(server, browser, tmp_path):
    """No floor to drive to, no liquid to grasp, the held object named rather than chosen, only containers to pour
    into, and a target never the held bottle's own water."""
    url, _ = server
    page = browser.new_page(viewport={"width": 1200, "height": 900})
    choose(page, url, Task("pour", ("obj27",)), "demonstrate")
    assert "floor" not in offered(page, "move_close", "a1") and "water_bottle" in offered(page, "move_close", "a1")
    grasp = offered(page, "grasp", "a1")
    assert "water_bottle" in grasp and not {"water", "tea", "juice", "coffee", "floor", "kitchen_table"} & set(grasp)
    assert grasp == sorted(grasp)
    assert "nothing is in the gripper" in page.inner_text("tr:has(#step-release), tr:has-text('release')")
    page.screenshot(path="/tmp/serve_step_forms_empty.png", full_page=True)
    click_step(page, Action("move_close", ("obj20",)))
    click_step(page, Action("grasp", ("obj20",)))
    assert page.locator("#step-grasp").count() == 0
    assert "the gripper holds water_bottle" in page.inner_text("#step-form")
    assert page.locator("#step-release b").inner_text() == "water_bottle"
    pour = offered(page, "follow_traj_pour", "a2")
    assert "cup" in pour and "mug" in pour and not {"water_bottle", "water", "magazine", "floor"} & set(pour)
    above = offered(page, "hold_above", "a2")
    assert "cup" in above and "trash_can" in above and not {"water_bottle", "water", "tea"} & set(above)
    assert "floor" in offered(page, "place_above", "a2")  # pick_and_place(x, floor) sets things down there
    page.screenshot(path="/tmp/serve_step_forms_held.png", full_page=True)
    click_step(page, Action("hold_above", ("obj20", "obj14")))
    click_step(page, Action("follow_traj_pour", ("obj20", "obj14")))
    click_step(page, Action("done"))
    assert "people/w0-env01.jsonl" in page.inner_text("#saved")


def test_leaving_a_task_with_unsaved_steps_asks_first(server, browser, tmp_path):
    """The browser's own question before the page is left for another address (a real beforeunload, the page's
    script), none while the person steps or follows the page's own links, whose pages keep the steps; starting
    another task asks on a page of the server's, and going back keeps the steps."""
    url, data = server
    page = browser.new_page(viewport={"width": 1200, "height": 900})
    dialogs: list[str] = []
    page.on("dialog", lambda d: (dialogs.append(d.type), d.dismiss()))
    choose(page, url, Task("pour", ("obj27",)), "demonstrate")
    page.click("#status")  # a person's gesture on the page: browsers ask only then
    page.goto(url + "/task")  # no step yet: nothing to lose, nothing asked
    assert dialogs == [] and page.url.endswith("/task")
    page.goto(url + "/demonstrate")
    click_step(page, Action("move_close", ("obj20",)))  # a form of the page: leaves without a question
    assert dialogs == [] and page.locator("#steps li").count() == 1
    assert page.get_attribute("body", "data-unsaved") == "1"
    page.click("#status")
    with pytest.raises(PlaywrightError, match="ERR_ABORTED"):  # a dismissed question keeps the person on the page
        page.goto(url + "/task")
    assert dialogs == ["beforeunload"] and page.url.endswith("/demonstrate")
    page.close()

    page = browser.new_page(viewport={"width": 1200, "height": 900})
    page.on("dialog", lambda d: (dialogs.append(d.type), d.accept()))
    choose(page, url, Task("pour", ("obj27",)), "demonstrate")
    room = page.inner_html("#scene")  # the room as the task starts
    click_step(page, Action("move_close", ("obj20",)))
    assert page.inner_html("#scene") != room  # the robot drove to the bottle
    page.click("#status")
    asked = len(dialogs)
    page.click("header a[href='/task']")  # a link of the page's own: no question, the task page says what is under way
    page.wait_for_url("**/task")
    assert len(dialogs) == asked and "pour(water), 1 step" in page.inner_text("#under-way")
    assert page.inner_html("#scene") == room  # where a new task would start, not where the one under way is
    page.go_back()  # back to the steps (from the browser's page cache, where it keeps one): they still ask
    page.wait_for_url("**/demonstrate")
    page.click("#status")
    page.goto(url + "/task")
    assert len(dialogs) == asked + 1 and dialogs[-1] == "beforeunload"
    page.select_option("#task-form select[name=task]", "throw_away")
    page.select_option("#task-form select[name=arg1]", "obj43")
    submit(page, "#task-form button[value=demonstrate]")
    assert "pour(water) is not finished: its 1 step so far is not saved" in page.inner_text("#confirm")
    page.screenshot(path="/tmp/serve_confirm.png", full_page=True)
    submit(page, "#back")
    assert page.locator("#steps li").count() == 1 and "pour(obj27)" in page.inner_text("#status")
    page.click("header a[href='/task']")
    page.wait_for_url("**/task")
    page.select_option("#task-form select[name=task]", "throw_away")
    page.select_option("#task-form select[name=arg1]", "obj43")
    submit(page, "#task-form button[value=demonstrate]")
    submit(page, "#discard-form button")
    assert "throw_away(obj43)" in page.inner_text("#status") and page.locator("#steps li").count() == 0
    assert not (data / "people").exists()


def click_object(page, obj: str) -> None:
    """Click an object in the top view as a person does: its shape, or a liquid's name in its container's label.

    Playwright clicks the middle of what it is given and fails if something else lies on top there."""
    shape = page.locator(f"#scene [data-object={obj}]")
    if shape.evaluate("e => e.tagName") == "g":
        shape = shape.locator("> rect")
    shape.click()


def test_objects_are_chosen_by_clicking_them_in_the_picture(server, browser, tmp_path):
    """A click fills the highlighted row's next empty list; an object the row does not offer is not taken and the
    message says why, by name; a second click unselects; the steps clicked are the steps recorded."""
    url, data = server
    page = browser.new_page(viewport={"width": 1200, "height": 900})
    choose(page, url, Task("pour", ("obj27",)), "demonstrate")
    message = page.locator("#pick-message")
    move = page.locator("#step-move_close select[name=a1]")
    assert move.input_value() == "" and page.locator("tr.picking #step-move_close").count() == 1
    click_object(page, "obj20")
    assert move.input_value() == "obj20"
    assert message.inner_text() == "move_close(water_bottle): click \u201cDo it\u201d in its row"
    assert page.locator("#scene .picked").evaluate_all("es => es.map(e => e.dataset.object)") == ["obj20"]
    submit(page, "#step-move_close button")
    assert page.locator("#steps li").all_inner_texts() == ["move_close(water_bottle) move_close(obj20)"]

    grasp = page.locator("#step-grasp select[name=a1]")
    page.click("tr:has(#step-grasp) td.primitive")  # the row to fill
    page.locator("#scene [data-object=obj02] > text").click()  # the kitchen table's name: the table is under items
    assert message.inner_text() == "kitchen_table is not offered for grasp: it takes movable things, never a liquid"
    click_object(page, "obj32")  # the coffee, in its teacup's label
    assert message.inner_text() == "coffee is not offered for grasp: it takes movable things, never a liquid"
    assert grasp.input_value() == "" and page.locator("#scene .picked").count() == 0
    click_object(page, "obj27")  # the water's name, which lies across the mug: grasp takes the mug, not the water
    assert grasp.input_value() == "obj13" and message.inner_text() == "grasp(mug): click \u201cDo it\u201d in its row"
    click_object(page, "obj27")  # again: the mug, unselected
    assert grasp.input_value() == "" and page.locator("#scene .picked").count() == 0
    click_object(page, "obj20")
    assert grasp.input_value() == "obj20"
    click_object(page, "obj20")  # again: unselected
    assert grasp.input_value() == "" and page.locator("#scene .picked").count() == 0
    assert message.inner_text() == "water_bottle is unselected: grasp(\u2026)"
    click_object(page, "obj20")
    submit(page, "#step-grasp button")

    above = page.locator("#step-hold_above select[name=a2]")
    page.click("tr:has(#step-hold_above) td.primitive")
    click_object(page, "obj14")
    assert above.input_value() == "obj14"
    assert message.inner_text() == "hold_above(water_bottle, cup): click \u201cDo it\u201d in its row"
    assert page.get_attribute("#scene [data-object=obj14]", "class") == "object picked"
    assert page.locator("tr.picking #step-hold_above").count() == 1
    page.locator("#scene [data-object=obj02] > text").click()  # the row has its object: the table is not taken
    assert above.input_value() == "obj14"
    assert message.inner_text() == ("hold_above(water_bottle, cup) has its objects; click one of them to unselect it "
                                    "first")
    click_object(page, "obj14")
    click_object(page, "obj14")
    page.screenshot(path=str(tmp_path / "clicked.png"), full_page=True)
    submit(page, "#step-hold_above button")
    page.click("tr:has(#step-follow_traj_pour) td.primitive")
    click_object(page, "obj14")
    submit(page, "#step-follow_traj_pour button")
    assert page.locator("#steps li").all_inner_texts()[2:] == [
        "hold_above(water_bottle, cup) hold_above(obj20,obj14)",
        "follow_traj_pour(water_bottle, cup) follow_traj_pour(obj20,obj14)"]
    click_step(page, Action("done"))
    record = json.loads((data / "people" / "w0-env01.jsonl").read_text())
    assert [(s["primitive"], s["args"]) for s in record["steps"]] == [
        ("move_close", ["obj20"]), ("grasp", ["obj20"]), ("hold_above", ["obj20", "obj14"]),
        ("follow_traj_pour", ["obj20", "obj14"])]


def test_a_task_and_a_step_of_assist_mode_are_chosen_in_the_picture(server, browser, tmp_path):
    """The task form: a liquid task takes the liquid (its name in the bottle's label), not the bottle; a
    one-object task takes no second; the assist page's own rows fill as the demonstrate page's."""
    url, _ = server
    page = browser.new_page(viewport={"width": 1200, "height": 900})
    page.goto(url + "/")
    page.select_option("#world-form select[name=env_id]", "env01")
    submit(page, "#world-form button")
    message = page.locator("#pick-message")
    first, second = page.locator("#task-form select[name=arg1]"), page.locator("#task-form select[name=arg2]")
    assert page.locator("#pick-hint").is_visible() and first.input_value() == ""
    page.select_option("#task-form select[name=task]", "pour")
    click_object(page, "obj20")
    assert first.input_value() == ""
    assert message.inner_text() == "pour takes a liquid, not water_bottle: click water in its label"
    click_object(page, "obj27")
    assert first.input_value() == "obj27" and message.inner_text().startswith("pour(water): start it")
    click_object(page, "obj14")  # pour takes one object
    assert second.input_value() == "" and message.inner_text().startswith("pour(water) has its objects")
    page.select_option("#task-form select[name=task]", "pour_to")
    click_object(page, "obj14")
    assert (first.input_value(), second.input_value()) == ("obj27", "obj14")
    assert message.inner_text() == "pour_to(water, cup): start it with a button of the task form"
    page.screenshot(path=str(tmp_path / "task.png"), full_page=True)
    submit(page, "#task-form button[value=assist]")
    assert "Task: pour_to(water, cup) (pour_to(obj27,obj14))" in page.inner_text("#status")
    move = page.locator("#step-move_close select[name=a1]")
    click_object(page, "obj20")
    assert move.input_value() == "obj20"
    submit(page, "#step-move_close button")
    assert page.locator("#steps li").first.inner_text().startswith("move_close(water_bottle) move_close(obj20)")


def open_room(page, url: str) -> None:
    page.goto(url + "/")
    page.select_option("#world-form select[name=env_id]", "env01")
    submit(page, "#world-form button")


def test_a_click_inside_an_objects_shape_picks_it_even_under_another_objects_label(server, browser):
    """In env01 the water's name, in its bottle's slanted label, lies across the mug: a click in the mug picks the
    mug. Every object but furniture, clicked in the middle of its shape (where no other shape is drawn over it),
    fills the task's list with itself, and a second click empties it."""
    url, _ = server
    page = browser.new_page(viewport={"width": 1200, "height": 2000})  # the whole picture in view
    open_room(page, url)
    page.select_option("#task-form select[name=task]", "throw_away")
    first = page.locator("#task-form select[name=arg1]")
    shapes = page.evaluate("""() => Array.from(document.querySelectorAll(
        '#scene g.object:not([data-kind=furniture]) > rect')).map(r => {
          const b = r.getBoundingClientRect(); return [r.parentNode.dataset.object, b.left, b.top, b.right, b.bottom];
        })""")
    checked, under_a_label = 0, 0
    for k, (obj, left, top, right, bottom) in enumerate(shapes):
        x, y = (left + right) / 2, (top + bottom) / 2
        if any(lo <= x <= hi and up <= y <= down for _, lo, up, hi, down in shapes[k + 1:]):
            continue  # another object's shape is drawn over its middle: that one is what the person sees there
        under_a_label += page.evaluate("([x, y]) => document.elementFromPoint(x, y).tagName", [x, y]) != "rect"
        page.mouse.click(x, y)
        assert first.input_value() == obj
        page.mouse.click(x, y)
        assert first.input_value() == ""
        checked += 1
    assert checked >= 8 and under_a_label >= 1


def test_another_task_empties_the_objects_it_does_not_take(server, browser):
    """pick_and_place(cup, kitchen_shelf) chosen, then throw_away: the second list is emptied and left out of the
    form, the message says what is chosen now, and the task starts with the one object it takes."""
    url, _ = server
    page = browser.new_page(viewport={"width": 1200, "height": 900})
    open_room(page, url)
    page.select_option("#task-form select[name=task]", "pick_and_place")
    page.select_option("#task-form select[name=arg1]", "obj14")
    page.select_option("#task-form select[name=arg2]", "obj08")
    page.select_option("#task-form select[name=task]", "throw_away")
    second = page.locator("#task-form select[name=arg2]")
    assert second.input_value() == "" and second.is_disabled()
    assert page.inner_text("#pick-message") == "throw_away(cup): start it with a button of the task form"
    submit(page, "#task-form button[value=demonstrate]")
    assert "Task: throw_away(cup)" in page.inner_text("#status")
    page.goto(url + "/task")
    page.select_option("#task-form select[name=task]", "pour_to")
    assert not second.is_disabled()


def test_without_the_script_the_lists_work_as_before(server, browser):
    """No empty first choice and no hint: the lists alone choose, and the picture is only a picture."""
    url, _ = server
    page = browser.new_context(java_script_enabled=False).new_page()
    choose(page, url, Task("pour", ("obj27",)), "demonstrate")
    assert page.locator("#step-move_close select[name=a1]").input_value() != ""
    assert page.locator("#step-move_close option[value='']").count() == 0
    assert not page.locator("#pick-hint").is_visible()
    page.locator("#scene [data-object=obj14] > rect").click()
    assert page.locator("#scene .picked").count() == 0 and page.inner_text("#pick-message") == ""
    click_step(page, Action("move_close", ("obj20",)))
    assert page.locator("#steps li").count() == 1


NAME_SIZES = """() => Array.from(document.querySelectorAll('#scene g.object:not([data-kind=furniture]) > text'))
    .map(t => { const m = t.getScreenCTM();
                return parseFloat(getComputedStyle(t).fontSize) * Math.hypot(m.a, m.b); })"""


def on_screen(page, selector: str) -> bool:
    """Whether what `selector` finds lies wholly inside the window as it is scrolled now."""
    box, view = page.locator(selector).bounding_box(), page.viewport_size
    return (box is not None and box["x"] >= 0 and box["y"] >= 0 and box["x"] + box["width"] <= view["width"]
            and box["y"] + box["height"] <= view["height"])


def click_middle(page, selector: str) -> None:
    """A click where the thing is on the screen now: Playwright's own click would scroll it into view first."""
    box = page.locator(selector).bounding_box()
    page.mouse.click(box["x"] + box["width"] / 2, box["y"] + box["height"] / 2)


@pytest.mark.parametrize("mode", ["demonstrate", "assist"])
def test_on_a_wide_window_the_picture_is_beside_the_rows_and_stays_in_view(server, browser, mode):
    """At 1200x900 a person clicks the bottle in the picture and its row's "Do it" without scrolling: both are on
    the screen as the page opens, the picture right of the rows, its names about 9.5 px; scrolled down to the last of
    the rules, the picture is still in view (sticky)."""
    url, _ = server
    page = browser.new_page(viewport={"width": 1200, "height": 900})
    choose(page, url, Task("pour", ("obj27",)), mode)
    bottle, button = "#scene g[data-object=obj20] > rect", "#step-move_close button"
    assert on_screen(page, bottle) and on_screen(page, button)
    assert page.locator("#scene").bounding_box()["x"] > page.locator(button).bounding_box()["x"] + 49  # beside
    assert min(page.evaluate(NAME_SIZES)) >= 9 and not page.locator("#scrolls").is_visible()
    click_middle(page, bottle)
    assert page.locator("#step-move_close select").input_value() == "obj20"
    assert page.evaluate("window.scrollY") == 0
    with page.expect_navigation():
        click_middle(page, button)
    assert page.locator("#steps li").first.inner_text().startswith("move_close(water_bottle)")
    page.evaluate("document.getElementById('rules').scrollIntoView(false)")  # the rules' last line at the bottom
    assert page.evaluate("window.scrollY") > 300 and on_screen(page, "#rules > ul:last-of-type > li:last-child")
    assert on_screen(page, bottle) and on_screen(page, "#scene g[data-object=obj17] > rect")  # the picture too
    page.screenshot(path=f"/tmp/web_layout/test_{mode}_1200_scrolled.png")


def test_on_a_narrow_window_the_picture_keeps_names_legible_and_scrolls_sideways(server, browser):
    """At 800 px the picture would draw names 7.5 px tall to fit: it keeps them 10 px or more, its smallest object
    6.5 px or more, and scrolls sideways in its frame (the heading says so) while the page does not; an object out
    of sight at the right is clicked after scrolling it into view."""
    url, _ = server
    page = browser.new_page(viewport={"width": 800, "height": 900})
    choose(page, url, Task("pour", ("obj27",)), "demonstrate")
    assert min(page.evaluate(NAME_SIZES)) >= 10
    widths = page.locator("#scene g.object > rect").evaluate_all("rs => rs.map(r => r.getBoundingClientRect().width)")
    assert min(widths) >= 6.5
    frame = page.locator("#picture .frame")
    assert frame.evaluate("f => f.scrollWidth > f.clientWidth + 50")
    assert page.evaluate("document.documentElement.scrollWidth") <= 800 and page.locator("#scrolls").is_visible()
    teacup = "#scene g[data-object=obj17] > rect"
    assert not on_screen(page, teacup)  # at the shelf's right end, out of the frame until scrolled to
    page.locator(teacup).scroll_into_view_if_needed()
    assert frame.evaluate("f => f.scrollLeft") > 0 and on_screen(page, teacup)
    click_middle(page, teacup)
    assert page.locator("#step-move_close select").input_value() == "obj17"
    page.screenshot(path="/tmp/web_layout/test_demonstrate_800_scrolled.png")


def test_the_picture_is_cropped_to_what_is_drawn_and_keeps_all_of_it(server, browser):
    """The top view's viewBox leaves out the empty margins the room was laid out on, but never a shape, a name (the
    longest slanted ones, the robot's label while it holds something), the robot or the arm's reach: in the 13
    benchmark rooms every one lies inside the picture as Chromium draws it."""
    url, _ = server
    page = browser.new_page(viewport={"width": 1700, "height": 1000})
    inside = """() => { const s = document.getElementById('scene').getBoundingClientRect();
        const drawn = document.querySelectorAll('#scene g.object > rect, #scene text, #scene > circle');
        return Array.from(drawn).filter(e => {
          const b = e.getBoundingClientRect();
          return b.left < s.left - 0.5 || b.top < s.top - 0.5 || b.right > s.right + 0.5 || b.bottom > s.bottom + 0.5;
        }).map(e => e.textContent || e.outerHTML.slice(0, 60)); }"""
    spare = """() => { const s = document.getElementById('scene').getBoundingClientRect();
        const all = Array.from(document.querySelectorAll('#scene g.object > rect, #scene text, #scene > circle'))
          .map(e => e.getBoundingClientRect());
        return (s.width * s.height) / ((Math.max(...all.map(b => b.right)) - Math.min(...all.map(b => b.left)))
          * (Math.max(...all.map(b => b.bottom)) - Math.min(...all.map(b => b.top)))); }"""
    for k in range(1, 14):
        page.goto(url + "/")
        page.select_option("#world-form select[name=env_id]", f"env{k:02d}")
        submit(page, "#world-form button")
        assert page.evaluate(inside) == [], f"env{k:02d}"
        assert page.evaluate(spare) < 1.25, f"env{k:02d}"  # not much room to spare around what is drawn
    choose(page, url, Task("pour", ("obj27",)), "demonstrate")
    for action in demonstrated(Task("pour", ("obj27",)))[:3]:  # the bottle held above the cup
        click_step(page, action)
    assert "robot, holding water_bottle (water), above cup" in page.locator("#scene").text_content()
    assert page.evaluate(inside) == []
