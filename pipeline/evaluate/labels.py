"""The names of Table I's methods as the tables print them, in the tables' order.

A module of its own so that the stages that only write tables (aggregate,
report) need not import the methods, and with them scikit-learn and Numba.
"""

METHOD_LABELS = {
    "chance": "chance",
    "multiclass": "multiclass",
    "symb_plan_svm": "symb-plan-svm",
    "symb_plan_manual": "symb-plan-manual",
    "only_edge": "only edge features",
    "only_clique": "only clique features",
    "full": "ours - full",
    # beyond the paper: relation features, then those with one kind of training data beyond the logs each;
    # their rows sit below the paper-faithful ones in every table
    "relations": "ours + relations",
    "chained": "ours + relations + chained starts",
    "dagger": "ours + relations + dagger",
}
