"""The experiments the pipeline runs on the methods: each a protocol over folds, conditions or environments.

`crossval.py` (Table I: grouped folds, steps and closed-loop programs),
`fold_models.py` (every model the experiments use, trained once into the
model store), `selection.py` (C chosen on the development world),
`robustness.py` (attribute noise and feedback), `recipes.py` (chained
tasks), `transfer.py` (whole rooms held out, models run in other rooms) and
`teaching.py` (what people's demonstrations buy); `outcome_cache.py` keeps
a fold's outcomes between runs. They reach every method
through its interface (`taskseq.evaluate`), run their jobs through
`taskseq.runtime.jobs`, and know nothing of the web app, MLflow or DVC: the
stages (`taskseq.stages`) put them together with those.
"""
