"""Figures reported by Sung, Selman and Saxena, for side-by-side comparison (not computed here)."""

TABLE1 = {  # method -> (average prim, average arg, sequence prim, sequence arg)
    "chance": (14.3, 0.7, 0.0, 0.0),
    "multiclass": (78.4, None, None, None),
    "symb-plan-svm": (84.6, 71.8, 58.4, 49.6),
    "symb-plan-manual": (84.6, 77.9, 58.4, 54.9),
    "only edge features": (48.9, 44.0, 0.0, 0.0),
    "only clique features": (91.9, 57.0, 45.0, 0.0),
    "ours - full": (96.7, 90.0, 91.6, 69.7),
}
NOISE = {0.0: 69.7, 0.1: 55.8, 0.4: 38.1}  # sequence accuracy at attribute flip rate r
FEEDBACK = {(2, "1"): 74.1, (3, "1"): 75.6, (2, "all"): 76.7, (3, "all"): 81.4, (2, "0"): 69.7, (3, "0"): 69.7}
RECIPES = {"no_feedback": 9, "feedback_first_step": 12, "recipes": 12}
DATASET = {"environments": 13, "objects": 43, "tasks": 5, "scenarios": 113, "sequences": 127, "steps": 736}
