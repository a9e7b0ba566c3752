"""Every method behind one interface, and how a step or a program is judged.

`methods.py` (the `Method` protocol and the built-in methods of Table I),
`registry.py` (the methods by name and label; methods added in
`taskseq.methods` register here), `folds.py` (grouped folds), `metrics.py`
(step accuracies) and `failures.py` (why a program fails). The experiments
that run the methods are in `taskseq.experiments`.
"""
