"""Teacher-forced training steps from demonstrations, and their files under data/features/.

Every demonstrated step becomes one `StepContext` with the demonstrated action
as its label, and every sequence adds a last step labelled `done` in its final
state, so a planner learns when to stop.

Files (written by `taskseq features`):
  steps.parquet       one row per step: ids, task, history, label, where its objects start
  objects.npz         CSR matrix, one row per (step, object): OBJECT_COLUMNS, then
                      TASK_REL_COLUMNS, then RELATION_COLUMNS; `object_ids` names the rows;
                      `collide_*` hold the colliding pairs (step row, i, j) in COO form

A step's candidates are not stored: `candidate_index(n)` enumerates them.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq
from scipy import sparse

from ..demonstrations.records import parse_record, state_from_dict
from ..runtime.atomic import atomic_directory
from ..sim.primitives import Action
from ..sim.tasks import TASKS
from .context import (
    HISTORY_ARG_COLUMNS,
    OBJECT_COLUMNS,
    RELATION_COLUMNS,
    TASK_REL_COLUMNS,
    StepContext,
    step_context,
)


@dataclass(frozen=True)
class StepMeta:
    sequence_id: str
    scenario_id: str
    step: int


def contexts_from_record(record: dict[str, Any]) -> list[StepContext]:
    specs, task, actions = parse_record(record)
    states = [s["state"] for s in record["steps"]] + [record["final_state"]]
    out = []
    for k, label in enumerate([*actions, Action("done")]):
        state = state_from_dict(specs, states[k])
        out.append(step_context(state, task, actions[:k], gold=label))
    return out


def build_steps(records: list[dict[str, Any]]) -> tuple[list[StepContext], list[StepMeta]]:
    contexts, meta = [], []
    for rec in records:
        ctxs = contexts_from_record(rec)
        contexts += ctxs
        meta += [StepMeta(rec["demo_id"], rec["scenario_id"], k) for k in range(len(ctxs))]
    return contexts, meta


STEP_SCHEMA = pa.schema([
    ("step_id", pa.int32()), ("sequence_id", pa.string()), ("scenario_id", pa.string()), ("step", pa.int32()),
    ("task", pa.string()), ("n_objects", pa.int32()), ("object_offset", pa.int64()),
    ("prev1", pa.int8()), ("prev2", pa.int8()),
    ("a1_prev1", pa.int16()), ("a2_prev1", pa.int16()), ("a1_prev2", pa.int16()), ("a2_prev2", pa.int16()),
    ("gold_primitive", pa.int8()), ("gold_a1", pa.int16()), ("gold_a2", pa.int16()),
])


def write_features(contexts: list[StepContext], meta: list[StepMeta], output: Path | str,
                   is_output: bool = True) -> None:
    """The steps as `taskseq features` writes them (`read_features` reads them back, the same bytes) into the
    folder `output`, replaced whole; `is_output` False for a cache entry (`runtime.atomic.atomic_directory`)."""
    rows, offsets, offset = [], [], 0
    ci, cj, cs = [], [], []
    for sid, ctx in enumerate(contexts):
        rows.append(np.hstack([ctx.objects, ctx.task_rel, ctx.relations]))
        offsets.append(offset)
        offset += ctx.n
        i, j = np.nonzero(ctx.collide)
        ci.append(i)
        cj.append(j)
        cs.append(np.full(len(i), sid))
    matrix = sparse.csr_matrix(np.vstack(rows))
    steps = {
        "step_id": list(range(len(contexts))),
        "sequence_id": [m.sequence_id for m in meta],
        "scenario_id": [m.scenario_id for m in meta],
        "step": [m.step for m in meta],
        "task": [TASKS[c.task] for c in contexts],
        "n_objects": [c.n for c in contexts],
        "object_offset": offsets,
        "prev1": [c.prev_prims[0] for c in contexts],
        "prev2": [c.prev_prims[1] for c in contexts],
        **{k: [c.prev_args[i] for c in contexts] for i, k in enumerate(HISTORY_ARG_COLUMNS)},
        **{k: [c.gold[i] for c in contexts] for i, k in enumerate(("gold_primitive", "gold_a1", "gold_a2"))},
    }
    with atomic_directory(output, output=is_output) as tmp:
        pq.write_table(pa.Table.from_pydict(steps, schema=STEP_SCHEMA), tmp / "steps.parquet",
                       compression="zstd", write_statistics=False)
        np.savez_compressed(
            tmp / "objects.npz",
            data=matrix.data, indices=matrix.indices, indptr=matrix.indptr, shape=np.array(matrix.shape),
            columns=np.array(OBJECT_COLUMNS + TASK_REL_COLUMNS + RELATION_COLUMNS),
            object_ids=np.array([o for c in contexts for o in c.object_ids]),
            collide_step=np.concatenate(cs), collide_i=np.concatenate(ci), collide_j=np.concatenate(cj),
        )


def read_features(directory: Path | str) -> tuple[list[StepContext], list[StepMeta]]:
    directory = Path(directory)
    for name in ("steps.parquet", "objects.npz"):
        if not (directory / name).is_file():
            what = "no such folder" if not directory.is_dir() else f"it holds no {name}"
            raise FileNotFoundError(f"{directory}: not a feature folder ({what}; `taskseq features` writes one)")
    steps = pq.read_table(directory / "steps.parquet", schema=STEP_SCHEMA).to_pylist()
    with np.load(directory / "objects.npz", allow_pickle=False) as z:
        columns = tuple(str(c) for c in z["columns"])
        if columns != OBJECT_COLUMNS + TASK_REL_COLUMNS + RELATION_COLUMNS:
            raise ValueError(f"{directory}/objects.npz: columns {columns} do not match this version's features")
        matrix = sparse.csr_matrix((z["data"], z["indices"], z["indptr"]), shape=tuple(z["shape"])).toarray()
        object_ids = [str(o) for o in z["object_ids"]]
        cs, ci, cj = z["collide_step"], z["collide_i"], z["collide_j"]
    k = len(OBJECT_COLUMNS)
    contexts, meta = [], []
    order = np.argsort(cs, kind="stable")
    cs, ci, cj = cs[order], ci[order], cj[order]
    bounds = np.searchsorted(cs, np.arange(len(steps) + 1))
    task_index = {t: i for i, t in enumerate(TASKS)}
    for row in steps:
        sid, n, o = row["step_id"], row["n_objects"], row["object_offset"]
        collide = np.zeros((n, n), dtype=bool)
        lo, hi = bounds[sid], bounds[sid + 1]
        collide[ci[lo:hi], cj[lo:hi]] = True
        contexts.append(StepContext(
            object_ids=object_ids[o : o + n],
            objects=matrix[o : o + n, :k],
            task_rel=matrix[o : o + n, k : k + len(TASK_REL_COLUMNS)],
            relations=matrix[o : o + n, k + len(TASK_REL_COLUMNS) :],
            collide=collide,
            task=task_index[row["task"]],
            prev_prims=(row["prev1"], row["prev2"]),
            prev_args=tuple(row[k] for k in HISTORY_ARG_COLUMNS),
            gold=(row["gold_primitive"], row["gold_a1"], row["gold_a2"]),
        ))
        meta.append(StepMeta(row["sequence_id"], row["scenario_id"], row["step"]))
    return contexts, meta
