"""The pipeline's stages, one module each, in the order `dvc.yaml` runs them.

Each module holds one `run` function: it takes its settings (`pipeline.settings`)
and the paths `dvc.yaml` declares, calls the library, writes only those paths,
and logs to the tracker it is given. Argument parsing stays in `pipeline.cli`.
"""

STAGES = ("select", "generate", "ingest", "features", "train", "pddl", "folds", "crossval", "noise", "feedback",
          "recipes", "aggregate", "people", "teach", "report")
