"""Stage `dev_world`: draw the development world, on which `select` chooses every setting, into its own folder.

It is drawn like a reported world (`world.family`), with the seed
`world.dev_seed`, which no reported world may share, and, when the family draws
its rooms, `select.environments` of them: a large benchmark chooses its
settings on a world of that size, not on one as large as the reported ones.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

from ..settings import Generate, Params, Procedural
from ..track.mlflow_runs import NO_RUN, Tracker
from .options import WorldFolderOptions
from .world_folder import draw_world


@dataclass(frozen=True)
class Settings:
    seed: int  # world.dev_seed
    family: str  # world.family, as the reported worlds
    procedural: Procedural  # the rooms' distribution, when the family draws them
    environments: int  # select.environments: how many rooms, when the family draws them

    def world(self) -> Generate:
        return Generate(self.seed, self.family, replace(self.procedural, environments=self.environments))


def settings(params: Params, world_seed: int | None = None) -> Settings:
    world = params.world
    if world.dev_seed in world.seeds:
        raise ValueError(f"params.yaml: world.dev_seed {world.dev_seed} is also a reported seed; settings must "
                         "be chosen on a world that is never reported")
    return Settings(world.dev_seed, world.family, params.procedural, params.select.environments)


def run(settings: Settings, options: WorldFolderOptions, tracker: Tracker = NO_RUN) -> None:
    draw_world(settings.world(), options.output, tracker)
    print(f"the development world (seed {settings.seed}) is in {options.output}")
