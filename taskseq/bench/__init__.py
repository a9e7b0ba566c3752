"""Benchmarks of the implementation, apart from the product and the pipeline: timings, never results.

`speed.py` is `taskseq bench` (training, per-step inference and the feature
files' memory on this machine; reports/bench.json, docs/speed.md), and
`scaling.py` is `taskseq scaling` (every per-world stage timed on procedural
worlds of growing size; reports/scaling.json, docs/scaling-benchmark.md).
Nothing of the pipeline imports them.
"""
