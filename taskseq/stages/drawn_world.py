"""Stage `drawn_world`: the world of rooms drawn by a reported seed, for the `scenes_world` stage's rooms held out.

Each reported world seed also draws a procedural world (params.yaml's
`procedural`: rooms, furniture and objects the catalog never had). It goes
through the same generate, ingest and features steps as a reported world
(`stages.world_folder`), into one folder.
"""

from __future__ import annotations

from ..settings import Generate, Params
from ..track.mlflow_runs import NO_RUN, Tracker
from .options import WorldFolderOptions
from .world_folder import draw_world


def settings(params: Params, world_seed: int | None = None) -> Generate:
    if world_seed is None:
        raise ValueError("drawn_world: name the world seed with --world-seed N")
    return Generate(world_seed, "procedural", params.procedural)


def run(settings: Generate, options: WorldFolderOptions, tracker: Tracker = NO_RUN) -> None:
    draw_world(settings, options.output, tracker)
    print(f"the drawn world of seed {settings.seed} is in {options.output}")
