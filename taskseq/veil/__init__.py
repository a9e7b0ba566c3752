"""VEIL-500 (Tell Me Dave, Cornell): people's demonstrated sequences in simulated kitchens and living rooms.

The release is read from a path and never copied into the repository (research-use license, docs/veil.md).
Modules: `xmltree` (XML with element lines), `pddl` (the release's domain), `release` (its XML files),
`state` (symbolic states and the domain's actions applied to them), `grounding` (one action line to a domain
action and to a learning step), `replay` (every sequence from its environment's initial state), `ingest`
(validate, replay, write Parquet tables).
"""

from .xmltree import VeilFormatError

__all__ = ["VeilFormatError"]
