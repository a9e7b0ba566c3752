"""Demonstrations: the log format people and the scripted demonstrator write, checked, generated and ingested.

`records.py` (a demonstration as a record, and `demonstration.schema.json`
beside it), `validate.py` (strict validation and replay in the simulator),
`generate.py` (the benchmark's logs from the demonstrator), `ingest.py`
(logs to Parquet and back), `people.py` (folders of people's records) and
`benchmark.py` (the benchmark decoded once from Parquet).
"""
