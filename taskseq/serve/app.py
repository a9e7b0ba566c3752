"""The web application: choose an environment and a task, demonstrate it, or correct the learned planner.

Every request reads its session (cookie id, server-side state) under that
session's lock; every form value is checked against the session's world
before anything changes; a refused step changes nothing. Pages follow
post/redirect/get, so reloading a page never repeats a step.
"""

from __future__ import annotations

import threading
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from flask import Flask, Response, g, redirect, render_template, request

from ..features.context import step_context
from ..learn.estimator import StepScorer
from ..learn.persist import policy_of
from ..plan.planner import Abstain, Policy, closes_loop, out_of_loops
from ..product import LIQUID_TASKS, ids_hint, in_names, parse_task, recorded_policy, told_apart
from ..sim.catalog import ENVIRONMENTS, OBJECTS_BY_ID
from ..sim.primitives import ALL_PRIMITIVES, ARITY, Action, PreconditionError
from ..sim.safety import RULES
from ..sim.state import WorldState
from ..sim.tasks import TASK_ARITY, Task
from ..words import counted
from .environments import SAFE_NAME, file_environment, named_files, read_named, world_environment
from .explain import explain
from .rules import UnsafeStep, argument_choices, preconditions, refusal
from .scene import support_tree, top_view
from .sessions import ASSIST, DEMONSTRATE, MODES, Activity, Session, SessionStore
from .writer import RecordWriter, WriterClosed, person_record

COOKIE = "taskseq_session"
MAX_UPLOAD = 2 * 1024 * 1024  # bytes of an uploaded environment file
# the only scripts are the server's own (/leave.js, /static/pick.js), never one inline, whatever an environment
# file holds; forms post only here
POLICY = ("default-src 'none'; script-src 'self'; style-src 'unsafe-inline'; img-src 'self'; form-action 'self'; "
          "frame-ancestors 'none'")
# Asks before a page with unsaved steps is left (closed, reloaded, another address): the browser's own
# `beforeunload` question. The page's own forms (a step, undo, done) and links (their pages keep the steps, and
# link back to the task under way) leave freely; starting another task or environment asks on the server, so that
# works without the script too.
LEAVE_SCRIPT = """\
"use strict";
(function () {
  var unsaved = Number(document.body.getAttribute("data-unsaved") || "0");
  if (!unsaved) { return; }
  var kept = false;  // left for another page of this server's: the steps stay where they are
  window.addEventListener("pageshow", function () { kept = false; });  // back again (Back, the page cache)
  document.addEventListener("submit", function () { kept = true; });
  window.addEventListener("click", function (event) {  // after the page's other scripts: only a click that leaves
    var link = event.target.closest && event.target.closest("a[href]");
    if (!link || event.defaultPrevented || event.button !== 0 ||
        event.ctrlKey || event.metaKey || event.shiftKey || event.altKey) { return; }  // a new tab or window
    if ((link.target && link.target !== "_self") || link.hasAttribute("download")) { return; }
    if (link.pathname === location.pathname && link.search === location.search && link.hash) { return; }
    if (link.origin === location.origin) { kept = true; }
  });
  window.addEventListener("beforeunload", function (event) {
    if (kept) { return; }
    event.preventDefault();
    event.returnValue = "";
  });
})();
"""


def steps_text(activity: Activity) -> list[str]:
    """The steps taken so far as the page names them (`product.in_names`)."""
    return [in_names(a, activity.states[k].specs) for k, a in enumerate(activity.actions)]


def corrections_text(corrected: list[int], n_steps: int) -> str:
    """Where a person chose other than the planner's best, as the saved page says it: the steps counted from 1 as
    the page lists them, and `done` (index `n_steps` in the record) by name: `at steps 1, 3 and at done`."""
    steps = [str(k + 1) for k in corrected if k < n_steps]
    parts = [f"at step{'s' if len(steps) > 1 else ''} {', '.join(steps)}"] if steps else []
    parts += ["at done"] if n_steps in corrected else []
    return " and ".join(parts)


def shown(state: WorldState, action: Action) -> tuple[str, str | None]:
    """A step as the page lists it: in the objects' names (where names repeat, where each object is:
    `told_apart`), and its ids where they differ (`ids_hint`)."""
    return in_names(action, state.specs, told_apart(state)), ids_hint(action, state.specs)


class Refused(Exception):
    """A request the page answers with a message and no change: bad input (400) or a refused step (409)."""

    def __init__(self, message: str, status: int = 400) -> None:
        super().__init__(message)
        self.status = status


@dataclass(frozen=True)
class Candidate:
    action: Action
    score: float
    why: str  # why it stands where it stands (`explain.explain`)


class Served:
    """What the application serves from: its folders, the sessions, the record writer and the planner."""

    def __init__(self, data: Path, model: Path, top_k: int) -> None:
        self.data = Path(data).resolve()
        self.people = self.data / "people"
        self.environments = self.data / "environments"
        self.model = Path(model)
        self.top_k = top_k
        self.sessions = SessionStore()
        self.writer = RecordWriter(self.people)
        # the model as its recorded policy, loaded once
        self._policy_for: Callable[[Task, WorldState], Policy] | None = None
        self._planner: StepScorer | None = None
        self._policy_name = ""
        self._planner_lock = threading.Lock()  # one scoring at a time: the model caches per batch

    def candidates(self, activity: Activity) -> tuple[list[Candidate], str | None]:
        """The planner's top k for the next step, in the policy's order, and why there are none when there are none.

        They are ranked by the policy the model file records (`greedy`: the best scores; `feasible`: the best
        scores among the steps that can run; `lookahead`: those, checked for the safety of what follows), as
        `taskseq plan` would run the model, and only steps the page would take are proposed
        (`product.runnable_first`); each says why it stands where it stands (`explain.explain`). A step's proposals
        are kept with the activity: the planner is deterministic, and the page and the step posted from it then
        agree on what proposal number k is."""
        known = activity.offers.get(tuple(activity.actions))
        if known is not None:  # a page shown again, or the step posted from it: ranked once
            return known
        with self._planner_lock:
            if self._policy_for is None:
                try:
                    planner = StepScorer.load(self.model)
                    self._policy_for = recorded_policy(planner, self.model, self.top_k)
                except (FileNotFoundError, ValueError) as err:
                    raise Refused(f"the planner cannot be loaded: {err}", 503) from None
                self._planner, self._policy_name = planner, policy_of(planner.meta_)
            ctx = step_context(activity.state, activity.task, activity.actions)
            history = tuple(activity.actions)
            try:
                policy = self._policy_for(activity.task, activity.states[0])
                # as `taskseq plan` runs it: the lookahead passes over a step that would close a loop of the task
                proposed = policy(ctx, activity.state)
                ranked = out_of_loops(policy, proposed, ctx, activity.states, history)
            except Abstain as why:
                found: tuple[list[Candidate], str | None] = ([], str(why))
            else:
                assert self._planner is not None
                reasons = explain(self._planner, self._policy_name, activity.task, activity.states[0], ctx,
                                  activity.state, ranked,
                                  closes_loop(activity.states, history) if ranked != proposed else None)
                found = ([Candidate(ctx.action(y), float(score), why)
                          for (y, score), why in zip(ranked, reasons, strict=True)], None)
        activity.offers[tuple(activity.actions)] = found
        return found


def create_app(data: Path, model: Path, top_k: int = 3) -> Flask:
    """The application; records go to `data/people/`, named environment files come from `data/environments/`."""
    app = Flask(__name__)
    app.config["MAX_CONTENT_LENGTH"] = MAX_UPLOAD
    app.jinja_env.filters["counted"] = counted  # the pages count as the messages do
    served = Served(data, model, top_k)
    app.extensions["taskseq"] = served

    def session() -> Session:
        g.sid, s = served.sessions.get(request.cookies.get(COOKIE))
        return s

    @app.after_request
    def headers(resp: Response) -> Response:
        if "sid" in g and request.cookies.get(COOKIE) != g.sid:
            resp.set_cookie(COOKIE, g.sid, httponly=True, samesite="Strict")
        resp.headers["Content-Security-Policy"] = POLICY
        resp.headers["X-Content-Type-Options"] = "nosniff"
        return resp

    def page(template: str, s: Session, status: int = 200, as_it_starts: bool = False,
             **kw: Any) -> tuple[str, int]:
        """`template` rendered with the environment's scene: the world of the task under way, or the room as every
        task starts in it where `as_it_starts` (the task page: a new task starts there, whatever one is under way)."""
        kw.setdefault("error", None)
        env = s.env
        # the steps a person would lose by leaving this page (the run page's only: elsewhere they are not in view)
        unsaved = len(s.activity.actions) if s.activity is not None and template == "run.html" else 0
        common: dict[str, Any] = {"env": env, "activity": s.activity, "unsaved": unsaved}
        if env is not None:
            state = s.activity.state if s.activity is not None and not as_it_starts else env.state
            common.update(view=top_view(state), tree=support_tree(state), state=state, shown=told_apart(state),
                          objects=sorted(state.specs.values(), key=lambda o: (o.name, o.id)))
        return render_template(template, **common, **kw), status

    def under_way(s: Session) -> str | None:
        """The task under way, as the links back to it name it."""
        activity = s.activity
        if activity is None:
            return None
        return in_names(activity.task, activity.state.specs, told_apart(activity.env.state))

    def choose_page(s: Session, status: int = 200, error: str | None = None):
        return page("choose.html", s, status, error=error, environments=ENVIRONMENTS, names=OBJECTS_BY_ID,
                    files=named_files(served.environments), folder=served.environments, under_way=under_way(s))

    def task_page(s: Session, status: int = 200, error: str | None = None, form: dict | None = None):
        return page("task.html", s, status, as_it_starts=True, error=error, tasks=TASK_ARITY,
                    liquid_tasks=LIQUID_TASKS, modes=MODES, form=form or {}, model=served.model, under_way=under_way(s))

    def run_page(s: Session, status: int = 200, error: str | None = None, refused: dict | None = None):
        """The page of the task under way; after a refused step (`refused`, its form) that step's row keeps the
        objects chosen in it, so that one wrong choice is mended without choosing the others again."""
        activity = s.activity
        assert activity is not None
        candidates, none_runs = served.candidates(activity) if activity.mode == ASSIST else ([], None)
        return page("run.html", s, status, error=error, none_runs=none_runs,
                    proposals=[(c, *shown(activity.state, c.action)) for c in candidates],
                    primitives=ALL_PRIMITIVES, arity=ARITY, goal=activity.goal_reached, preconditions=preconditions(),
                    safety=RULES, choices=argument_choices(activity.state),
                    task_text=under_way(s),
                    task_ids=ids_hint(activity.task, activity.state.specs),
                    steps=[shown(activity.states[k], a) for k, a in enumerate(activity.actions)],
                    refused=refused or {})

    def stale_page(activity: Activity) -> str | None:
        """Why the posted form does not fit the task under way, or None where it does.

        A page's forms carry the activity they were drawn for and its step count. Another tab of the same browser
        (one session) may since have dropped that task and started another, which is often at the same step: the
        step count alone would let a step land in a task the person never saw, so the activity is checked first,
        and the message names the task now under way. A form without an activity (a script's, an older page's)
        is checked by its step count alone."""
        steps = counted(len(activity.actions), "step")
        drawn_for = request.form.get("activity")
        if drawn_for is not None and drawn_for != str(activity.id):
            task = in_names(activity.task, activity.state.specs, told_apart(activity.env.state))
            return (f"this page was for a task no longer under way: since it was drawn, {task} was started in this "
                    f"browser ({steps} now)")
        if request.form.get("n", "") != str(len(activity.actions)):
            return f"this page was out of date (the demonstration has {steps} now)"
        return None

    def confirm_page(s: Session, action: str, fields: dict[str, str], leaving_for: str):
        """Asks before the steps of the task under way are dropped: posting `fields` again with `discard` drops
        them; the other button goes back to the task. Nothing changes until the person answers."""
        activity = s.activity
        assert activity is not None
        stale = stale_page(activity) if request.form.get("discard") == "yes" else None  # asked on a page since
        error = None if stale is None else f"{stale}; nothing was dropped: drop the steps below, or go back to them"
        return page("confirm.html", s, 409, error=error, action=action, fields=fields, leaving_for=leaving_for,
                    task_text=in_names(activity.task, activity.state.specs), steps=steps_text(activity))

    def unsaved(s: Session) -> bool:
        """Whether starting something else would drop steps the person has not agreed to drop: agreeing (`discard`)
        counts only for the task and steps its page listed, not for those another tab has taken since."""
        if s.activity is None or not s.activity.actions:
            return False
        if request.form.get("discard") != "yes":
            return True
        return "activity" in request.form and stale_page(s.activity) is not None  # a script's yes is taken as is

    @app.get("/leave.js")
    def leave_script():
        return Response(LEAVE_SCRIPT, mimetype="text/javascript")

    @app.errorhandler(413)
    def too_large(_err):
        s = session()
        with s.lock:
            return choose_page(s, 413, f"the file is larger than {MAX_UPLOAD // 1024 // 1024} MB; nothing was read")

    @app.get("/")
    def choose():
        s = session()
        with s.lock:
            return choose_page(s)

    @app.post("/environment")
    def environment():
        s = session()
        with s.lock:
            form = request.form
            try:
                source = form.get("source", "")
                if source == "pending":  # confirmed on the page that asked before dropping unsaved steps
                    if s.pending_env is None:
                        raise Refused("no environment is waiting to be used; choose one")
                    asked = form.get("pending")  # the one the page asked about (a script may leave it out)
                    if asked is not None and asked != s.pending_env.env_id:  # another tab chose another since
                        raise Refused(f"this page asked about another environment than the one now waiting "
                                      f"({s.pending_env.label}, chosen since in this browser); nothing was changed: "
                                      "choose again", 409)
                    env = s.pending_env
                elif source == "world":
                    seed_text = form.get("seed", "").strip()
                    if not seed_text.isdigit():
                        raise Refused(f"world seed must be a whole number from 0, got {seed_text!r}")
                    env = world_environment(int(seed_text), form.get("env_id", ""))
                elif source == "named":
                    env = read_named(served.environments, form.get("name", ""))
                elif source == "upload":
                    upload = request.files.get("file")
                    if upload is None or not upload.filename:
                        raise Refused("choose an environment file (.json) to upload")
                    try:
                        text = upload.read().decode("utf-8")
                    except UnicodeDecodeError:
                        raise Refused(f"{upload.filename}: not a text file (UTF-8 JSON expected)") from None
                    env = file_environment(upload.filename, text)
                else:
                    raise Refused(f"unknown environment source {source!r}: world, named or upload")
            except Refused as err:
                return choose_page(s, err.status, str(err))
            except (ValueError, KeyError) as err:  # a file's error names the file and its field
                # a KeyError's str() is its message quoted: the message alone, so a quote inside it stays whole
                return choose_page(s, 400, str(err.args[0]) if isinstance(err, KeyError) and err.args else str(err))
            if unsaved(s):
                s.pending_env = env
                return confirm_page(s, "/environment", {"source": "pending", "pending": env.env_id},
                                    f"the environment {env.label}")
            s.env, s.activity, s.pending_env = env, None, None
            return redirect("/task", 303)

    @app.get("/task")
    def task():
        s = session()
        with s.lock:
            if s.env is None:
                return redirect("/", 303)
            return task_page(s)

    @app.post("/task")
    def start():
        s = session()
        with s.lock:
            if s.env is None:
                return choose_page(s, 409, "choose an environment first")
            form = request.form
            try:
                mode = form.get("mode", "")
                if mode not in MODES:
                    raise Refused(f"unknown mode {mode!r}: {' or '.join(MODES)}")
                participant = form.get("participant", "").strip()
                if participant and not SAFE_NAME.match(participant):
                    raise Refused(f"participant id {participant!r}: use letters, digits, _ and - only "
                                  f"(at most 64, starting with a letter or digit), or leave it empty")
                args = [a.strip() for a in (form.get("arg1", ""), form.get("arg2", "")) if a.strip()]
                for a in args:
                    if a not in s.env.state.specs:
                        raise Refused(f"unknown object {a!r}: it is not in this environment")
                wanted = TASK_ARITY.get(form.get("task", ""))
                if wanted is not None and len(args) != wanted:
                    raise Refused(f"{form['task']} takes {counted(wanted, 'object', spelled=True)}, got "
                                  f"{counted(len(args), 'object', spelled=True)}" + (
                                      f" ({', '.join(s.env.state.specs[a].name for a in args)})" if args else "")
                                  + ("; set the second object to (none)" if len(args) > wanted else ""))
                task = parse_task(f"{form.get('task', '')}({','.join(args)})", s.env.state)
            except (Refused, ValueError) as err:
                return task_page(s, getattr(err, "status", 400), str(err), dict(form))
            if unsaved(s):
                fields = {k: form.get(k, "") for k in ("task", "arg1", "arg2", "participant", "mode")}
                return confirm_page(s, "/task", fields, in_names(task, s.env.state.specs))
            s.activity = Activity(s.env, task, mode, participant or None)
            return redirect(f"/{mode}", 303)

    def show(mode: str):
        s = session()
        with s.lock:
            if s.activity is None or s.activity.mode != mode:
                return redirect("/task" if s.env is not None else "/", 303)
            try:
                return run_page(s)
            except Refused as err:
                return task_page(s, err.status, str(err))

    app.add_url_rule("/demonstrate", "demonstrate", lambda: show(DEMONSTRATE))
    app.add_url_rule("/assist", "assist", lambda: show(ASSIST))

    def current(s: Session) -> Activity:
        """The task under way, if the form was drawn for it as it stands: refused (409, nothing done) otherwise."""
        if s.activity is None:
            raise Refused("no task is under way in this browser; choose one first", 409)
        if (stale := stale_page(s.activity)) is not None:
            raise Refused(f"{stale}; nothing was done", 409)
        return s.activity

    def chosen(activity: Activity) -> tuple[Action, bool]:
        """The step the form names and whether it overrides the planner's best (assist only)."""
        form = request.form
        candidates = served.candidates(activity)[0] if activity.mode == ASSIST else []
        if "choice" in form:
            if not candidates:
                raise Refused("there are no proposals to choose from in this mode")
            pick = form["choice"]
            if not pick.isdigit() or int(pick) >= len(candidates):
                raise Refused(f"no proposal number {pick!r}: choose one of the {len(candidates)} shown")
            return candidates[int(pick)].action, int(pick) != 0
        primitive = form.get("primitive", "")
        if primitive not in ARITY:
            raise Refused(f"unknown primitive {primitive!r}; known: {', '.join(ALL_PRIMITIVES)}")
        args = [a.strip() for a in (form.get("a1", ""), form.get("a2", "")) if a.strip()]
        for a in args:
            if a not in activity.state.specs:
                raise Refused(f"unknown object {a!r}: it is not in this environment")
        if len(args) != ARITY[primitive]:
            raise Refused(f"{primitive} takes {counted(ARITY[primitive], 'object', spelled=True)}, "
                          f"got {counted(len(args), 'object', spelled=True)}")
        action = Action(primitive, tuple(args))  # ValueError names two objects that must differ
        return action, bool(candidates) and action != candidates[0].action

    @app.post("/step")
    def step():
        s = session()
        with s.lock:
            try:
                activity = current(s)
                action, overridden = chosen(activity)
                if action.primitive == "done":
                    return finish(s, activity, overridden)
                activity.step(action, overridden)
            except PreconditionError as err:
                state = s.activity.state
                return run_page(s, 409, f"{in_names(err.action, state.specs)} is refused: {refusal(state, err)} "
                                        f"(check: {err.check}); nothing was done", dict(request.form))
            except UnsafeStep as err:
                return run_page(s, 409, f"{in_names(err.action, s.activity.state.specs)} is refused: {err.reason}; "
                                        "nothing was done", dict(request.form))
            except Refused as err:
                return (run_page(s, err.status, str(err)) if s.activity is not None
                        else choose_page(s, err.status, str(err)))
            except ValueError as err:
                return run_page(s, 400, str(err), dict(request.form))
            return redirect(f"/{activity.mode}", 303)

    def finish(s: Session, activity: Activity, overridden: bool):
        if not activity.actions:
            raise Refused("done is refused: no step has been taken yet", 409)
        if not activity.goal_reached:
            raise Refused(f"done is refused: the goal of {in_names(activity.task, activity.state.specs)} does not hold "
                          "yet", 409)
        corrected = None
        if activity.mode == ASSIST:
            corrected = activity.corrected + ([len(activity.actions)] if overridden else [])
        record = person_record(activity.env, activity.task, activity.actions, activity.participant, corrected)
        try:
            path = served.writer.append(record)
        except (WriterClosed, OSError) as err:
            raise Refused(f"the demonstration could not be recorded: {err}; it is kept, try done again", 503) from None
        s.finished = {"demo_id": record["demo_id"], "file": str(path.relative_to(served.data)),
                      "steps": steps_text(activity),
                      "task": in_names(activity.task, activity.state.specs),
                      "corrected": None if corrected is None else corrections_text(corrected, len(activity.actions)),
                      "participant": activity.participant}
        s.activity = None
        return redirect("/finished", 303)

    @app.post("/undo")
    def undo():
        s = session()
        with s.lock:
            try:
                current(s).undo()
            except Refused as err:
                return (run_page(s, err.status, str(err)) if s.activity is not None
                        else choose_page(s, err.status, str(err)))
            except ValueError as err:
                return run_page(s, 400, str(err))
            return redirect(f"/{s.activity.mode}", 303)

    @app.get("/finished")
    def finished():
        s = session()
        with s.lock:
            if s.finished is None:
                return redirect("/", 303)
            return page("finished.html", s, finished=s.finished)

    return app
