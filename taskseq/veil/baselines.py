"""Baselines of the people's-demonstrations evaluation, each speaking `methods.VeilMethod`.

- `Chance`: every candidate step of the state in a seeded random order.
- `MostFrequent`: the signature most frequent after the previous one for the objective, with the argument
  categories most frequent for (objective, signature), mapped to the state's objects.
- `NearestDemonstration`: the training sequence of the objective whose environment is most like the state's,
  replayed from the step the history has reached, its objects mapped to the state's by name, else by category.
- `MulticlassSVM`: a linear SVM predicting the signature from the objective, the previous two signatures and the
  categories the robot grasps and is near; arguments as `MostFrequent`'s, for the predicted signature.

A "verb" here is a signature of `features.SIGNATURES` (a verb with its arity: `pour` with one argument and with
two are two signatures), so that a predicted verb says how many objects it takes. Categories are compared without
case. Every method yields each step at most once, only steps whose objects are objects of the state's environment
(`state.world.objects`), and the same ranking for the same fit and call whatever calls came before.
"""

from __future__ import annotations

import hashlib
import itertools
from collections import Counter
from collections.abc import Iterable, Iterator, Sequence
from dataclasses import dataclass, field

import numpy as np
from sklearn.feature_extraction import DictVectorizer
from sklearn.svm import LinearSVC

from .features import DONE, SIGNATURES, signature_of
from .grounding import Step
from .methods import training_steps
from .release import environment_file
from .replay import Replay
from .state import ROBOT, State

Signature = tuple[str, int]
START: Signature = ("<start>", 0)  # the "previous signature" before a sequence's first step


# shared helpers -------------------------------------------------------------------------------------------------
def category(state: State, name: str) -> str:
    """An object's category, lower-cased (the release's uncatalogued base names vary in case)."""
    return state.world.objects[name].category.lower()


def signature(step: Step) -> Signature:
    return SIGNATURES[signature_of(step)]


def arguments(step: Step) -> tuple[str, ...]:
    return tuple(a for a in (step.a1, step.a2) if a is not None)


def make_step(sig: Signature, objects: Sequence[str]) -> Step:
    return Step(sig[0], *objects)


def candidates(state: State, signatures: Iterable[Signature] = SIGNATURES) -> Iterator[Step]:
    """Every step of `signatures` over the state's objects: each object for one argument, each ordered pair of
    distinct objects for two, in world order."""
    names = list(state.world.objects)
    for sig in signatures:
        if sig[1] == 0:
            yield make_step(sig, ())
        elif sig[1] == 1:
            for n in names:
                yield make_step(sig, (n,))
        else:
            for a, b in itertools.permutations(names, 2):
                yield make_step(sig, (a, b))


def ranked_keys(counts: Counter, key=None) -> list:
    """The keys of `counts`, most frequent first, ties in the keys' own order (not the order they were seen)."""
    return sorted(counts, key=lambda k: (-counts[k], key(k) if key else k))


def _sig_key(sig: Signature) -> tuple[int, Signature]:
    return (SIGNATURES.index(sig) if sig in SIGNATURES else -1, sig)


def unique(steps: Iterable[Step]) -> Iterator[Step]:
    seen: set[Step] = set()
    for s in steps:
        if s not in seen:
            seen.add(s)
            yield s


def prev_signature(history: Sequence[Step], back: int = 1) -> Signature:
    return signature(history[-back]) if len(history) >= back else START


def relation_categories(state: State, relation: str) -> list[str]:
    """Categories of the objects the robot is `relation` (Near, Grasping) to, sorted, with repeats."""
    return sorted(category(state, f[2]) for f in state.facts
                  if f[0] == relation and f[1] == ROBOT and f[2] in state.world.objects)


@dataclass
class ArgumentModel:
    """Which argument categories go with a signature: counts per (objective, signature), and per signature."""

    by_objective: dict[tuple[str, Signature], Counter] = field(default_factory=dict)
    by_signature: dict[Signature, Counter] = field(default_factory=dict)

    def add(self, state: State, objective: str, step: Step) -> None:
        sig = signature(step)
        cats = tuple(category(state, a) for a in arguments(step))
        self.by_objective.setdefault((objective, sig), Counter())[cats] += 1
        self.by_signature.setdefault(sig, Counter())[cats] += 1

    def steps(self, state: State, sig: Signature, objective: str) -> Iterator[Step]:
        """Steps of `sig` whose argument categories were seen with it, most frequent for the objective first, then
        for any objective; a category tuple gives its objects in world order (first the first object of each
        category); a tuple with a category the state holds no object of is skipped."""
        by_cat: dict[str, list[str]] = {}
        for name in state.world.objects:
            by_cat.setdefault(category(state, name), []).append(name)
        for counts in (self.by_objective.get((objective, sig), Counter()), self.by_signature.get(sig, Counter())):
            for cats in ranked_keys(counts):
                pools = [by_cat.get(c, []) for c in cats]
                for objs in itertools.product(*pools):
                    if len(set(objs)) == len(objs):
                        yield make_step(sig, objs)

    def ranked(self, state: State, signatures: Sequence[Signature], objective: str) -> Iterator[Step]:
        """For each signature in the order given, its seen argument categories; then every other candidate."""
        def all_steps() -> Iterator[Step]:
            for sig in signatures:
                yield from self.steps(state, sig, objective)
            yield from candidates(state, signatures)

        return unique(all_steps())


def complete(order: Iterable[Signature]) -> list[Signature]:
    """`order` without repeats, then every signature it left out, in `SIGNATURES` order."""
    out = list(dict.fromkeys(s for s in order if s in SIGNATURES))
    return out + [s for s in SIGNATURES if s not in out]


# the baselines --------------------------------------------------------------------------------------------------
@dataclass
class Chance:
    """Every candidate step of the state (`candidates`) in a random order. The order is drawn from a generator
    seeded by (seed, objective, len(history), environment id) through SHA-256, so a call's ranking does not depend
    on the calls before it, nor on Python's hash seed."""

    seed: int = 0
    name: str = "chance"

    def fit(self, train: Sequence[Replay]) -> Chance:
        return self

    def call_seed(self, state: State, history: Sequence[Step], objective: str) -> int:
        text = "\0".join((str(self.seed), objective, str(len(history)), state.world.env_id))
        return int.from_bytes(hashlib.sha256(text.encode()).digest()[:8], "little")

    def ranked(self, state: State, history: Sequence[Step], objective: str) -> Iterator[Step]:
        names = list(state.world.objects)
        n = len(names)
        sizes = [1 if k == 0 else n if k == 1 else n * (n - 1) for _, k in SIGNATURES]
        starts = np.cumsum([0] + sizes)
        rng = np.random.default_rng(self.call_seed(state, history, objective))
        for i in rng.permutation(int(starts[-1])):  # decode the i-th of `candidates(state)` without building them
            block = int(np.searchsorted(starts, i, side="right")) - 1
            sig, j = SIGNATURES[block], int(i - starts[block])
            if sig[1] == 0:
                yield make_step(sig, ())
            elif sig[1] == 1:
                yield make_step(sig, (names[j],))
            else:
                a, b = divmod(j, n - 1)
                yield make_step(sig, (names[a], names[b + (b >= a)]))


@dataclass
class MostFrequent:
    """The signature most frequent after the previous one (the sequence's start for the first step) for the
    objective in training, falling back to the objective's most frequent signatures, then to the overall ones, then
    to every other signature; each signature's arguments are the categories most frequent with it for the objective
    (then for any objective), mapped to the state's objects (`ArgumentModel`); then every other candidate step."""

    name: str = "most-frequent"
    after_: dict[tuple[str, Signature], Counter] = field(init=False, repr=False, default_factory=dict)
    objective_: dict[str, Counter] = field(init=False, repr=False, default_factory=dict)
    overall_: Counter = field(init=False, repr=False, default_factory=Counter)
    arguments_: ArgumentModel = field(init=False, repr=False, default_factory=ArgumentModel)

    def fit(self, train: Sequence[Replay]) -> MostFrequent:
        self.after_, self.objective_, self.overall_, self.arguments_ = {}, {}, Counter(), ArgumentModel()
        for state, history, objective, step in training_steps(train):
            sig = signature(step)
            self.after_.setdefault((objective, prev_signature(history)), Counter())[sig] += 1
            self.objective_.setdefault(objective, Counter())[sig] += 1
            self.overall_[sig] += 1
            self.arguments_.add(state, objective, step)
        return self

    def signatures(self, history: Sequence[Step], objective: str) -> list[Signature]:
        levels = (self.after_.get((objective, prev_signature(history)), Counter()),
                  self.objective_.get(objective, Counter()), self.overall_)
        return complete(s for counts in levels for s in ranked_keys(counts, _sig_key))

    def ranked(self, state: State, history: Sequence[Step], objective: str) -> Iterator[Step]:
        return self.arguments_.ranked(state, self.signatures(history, objective), objective)


def room(env_id: str) -> str | None:
    found = environment_file(env_id)
    return found[0] if found else None


def category_bag(state: State) -> Counter:
    return Counter(category(state, n) for n in state.world.objects)


@dataclass
class NearestDemonstration:
    """Replay the objective's training sequence whose environment is nearest the state's: the same room first
    (kitchen or living room, from the environment id), then the largest overlap of the two environments' multisets
    of object categories, ties by sequence id. Its kept step at index len(history) comes first (`done` once it has
    run out), each object mapped to the state's object of the same name compared without case, else to the first
    object of its category (for a second argument, the first other than the first argument), else the step is
    skipped; then its later steps, then `done`, then its earlier steps, as fallbacks. An objective with no
    training sequence uses every training sequence. Sequences with no kept step are not demonstrations."""

    name: str = "nearest-demonstration"
    demos_: list[Replay] = field(init=False, repr=False, default_factory=list)
    bags_: dict[str, Counter] = field(init=False, repr=False, default_factory=dict)

    def fit(self, train: Sequence[Replay]) -> NearestDemonstration:
        self.demos_ = [r for r in train if r.kept]
        self.bags_ = {r.point.seq_id: category_bag(r.initial) for r in self.demos_}
        return self

    def nearest(self, state: State, objective: str) -> Replay | None:
        pool = [r for r in self.demos_ if r.point.objective == objective] or self.demos_
        if not pool:
            return None
        here, bag = room(state.world.env_id), category_bag(state)

        def key(r: Replay) -> tuple[bool, int, str]:
            overlap = sum((self.bags_[r.point.seq_id] & bag).values())
            return (room(r.point.env_id) != here, -overlap, r.point.seq_id)

        return min(pool, key=key)

    @staticmethod
    def map_step(step: Step, source: State, state: State) -> Step | None:
        """`step` of the demonstration's environment (`source`) in `state`'s, or None when an object has no match."""
        out: list[str] = []
        for name in arguments(step):
            found = state.world.names.strict(name)
            if found is None or found in out:
                cat = category(source, name) if name in source.world.objects else None
                found = next((n for n in state.world.objects if category(state, n) == cat and n not in out), None)
            if found is None:
                return None
            out.append(found)
        return Step(step.verb, *out)

    def ranked(self, state: State, history: Sequence[Step], objective: str) -> Iterator[Step]:
        demo = self.nearest(state, objective)
        if demo is None:
            yield Step(DONE)
            return
        steps = list(demo.kept) + [Step(DONE)]
        at = min(len(history), len(steps) - 1)
        order = steps[at:] + steps[:at]
        mapped = (self.map_step(s, demo.initial, state) for s in order)
        yield from unique(s for s in mapped if s is not None)


@dataclass
class MulticlassSVM:
    """A linear SVM (`LinearSVC`, one-vs-rest, squared hinge) predicting the step's signature from the
    objective (one-hot), the previous two signatures (one-hot, the start for missing ones) and the categories the
    robot grasps and is near (bags: counts per category); signatures ranked by the decision function, those never
    seen in training after, in `SIGNATURES` order; each signature's arguments as `MostFrequent`'s
    (`ArgumentModel`, conditioned on the signature and objective), then every other candidate step.

    `tol` and `max_iter` are LinearSVC's defaults; `dual="auto"` (the solver picks the primal when there are more
    samples than features, as on the release) with a fixed `random_state` makes the fit deterministic."""

    C: float = 1.0
    random_state: int = 0
    max_iter: int = 1000
    name: str = "multiclass-svm"
    vectorizer_: DictVectorizer = field(init=False, repr=False)
    svm_: LinearSVC | None = field(init=False, repr=False, default=None)
    classes_: list[Signature] = field(init=False, repr=False, default_factory=list)
    arguments_: ArgumentModel = field(init=False, repr=False, default_factory=ArgumentModel)

    @staticmethod
    def features(state: State, history: Sequence[Step], objective: str) -> dict[str, float]:
        x: dict[str, float] = {f"objective={objective}": 1.0}
        for back in (1, 2):
            verb, arity = prev_signature(history, back)
            x[f"prev{back}={verb}/{arity}"] = 1.0
        for relation, prefix in (("Grasping", "grasps"), ("Near", "near")):
            for cat, n in Counter(relation_categories(state, relation)).items():
                x[f"{prefix}={cat}"] = float(n)
        return x

    def fit(self, train: Sequence[Replay]) -> MulticlassSVM:
        X, y = [], []
        self.arguments_ = ArgumentModel()
        for state, history, objective, step in training_steps(train):
            X.append(self.features(state, history, objective))
            y.append(signature_of(step))
            self.arguments_.add(state, objective, step)
        labels = sorted(set(y))
        self.classes_ = [SIGNATURES[i] for i in labels]
        self.svm_ = None
        if len(labels) > 1:  # LinearSVC needs two classes; with one, it is the prediction (with none, no sample)
            # dense: LinearSVC refuses the int64-indexed sparse matrix DictVectorizer gives
            self.vectorizer_ = DictVectorizer(sort=True, sparse=False)
            matrix = self.vectorizer_.fit_transform(X)
            self.svm_ = LinearSVC(C=self.C, dual="auto", random_state=self.random_state, max_iter=self.max_iter)
            self.svm_.fit(matrix, np.array(y))
        return self

    def signatures(self, state: State, history: Sequence[Step], objective: str) -> list[Signature]:
        if self.svm_ is None:
            return complete(self.classes_)
        scores = self.svm_.decision_function(self.vectorizer_.transform([self.features(state, history, objective)]))
        scores = np.atleast_1d(scores[0])
        if len(self.classes_) == 2:  # a binary LinearSVC scores the second class only
            scores = np.array([-scores[0], scores[0]])
        order = sorted(range(len(self.classes_)), key=lambda i: (-scores[i], i))
        return complete(self.classes_[i] for i in order)

    def ranked(self, state: State, history: Sequence[Step], objective: str) -> Iterator[Step]:
        return self.arguments_.ranked(state, self.signatures(state, history, objective), objective)
