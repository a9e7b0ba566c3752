"""What every `taskseq` command needs to run but is not the method: atomic writes, stopping, memory, where jobs run.

`atomic.py` replaces an output whole or not at all, `stopping.py` turns
Ctrl-C and SIGTERM into exceptions held back while a record is written,
`memory.py` keeps the memory a process frees for its next allocation,
`jobs.py` runs a grid of independent jobs on joblib's processes or a Dask
cluster, `sources.py` reads which project files a module runs, and
`cache.py` names the folder where fits and fold outcomes are kept between
runs. None of them imports anything else of the project, and none changes a
result: the same inputs give the same bytes with or without them.

MLflow's writer process stays in `taskseq.track` with the runs it writes: it
serves recording, which a command can turn off (`--no-mlflow`) and the
commands that are not stages never use, and it shares the store's names and
the runs' protocol with `track/mlflow_runs.py`.
"""
