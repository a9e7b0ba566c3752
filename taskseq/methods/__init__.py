"""Methods added beside Table I's, one module each.

Every module in this package is imported the first time the methods are
listed (`taskseq.evaluate.registry.added_methods`), and registers its method
with `@register(name, label)`. From then on the method has a row in Table I
(per world and over worlds), a child run in MLflow, and, when it is an MRF
method, its fold models in the model store. `docs/extending.md` walks through
adding one.
"""
