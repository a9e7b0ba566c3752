"""`taskseq serve`: people demonstrate tasks and correct the learned planner in a browser.

Server-rendered pages (Flask, Jinja with autoescape), one server-side session
per browser, and finished demonstrations appended as whole records of the log
format to `<data>/people/<environment>.jsonl`, so `taskseq ingest` and
`taskseq replay` read them like the scripted demonstrator's logs.
"""
