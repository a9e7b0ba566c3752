"""Every method behind one interface, and how a step or a program is judged.

`methods.py` (the `Method` protocol and the kinds of method Table I's are
made of: chance, the multiclass SVM, the symbolic planners and `ScorerMethod`,
the learned scorer with its training data and policy),
`folds.py` (grouped folds), `metrics.py` (step accuracies) and `failures.py`
(why a program fails). Table I's methods themselves, one spec each, are in
`taskseq.methods`; the experiments that run them are in `taskseq.experiments`.
"""
