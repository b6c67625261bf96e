"""Automatic tuning of any scene keys with CMA-ES on the batch engine (`python -m bwr_twin.tune`).

    objective.py  a candidate's score from its runs' metrics: weighted, normalised, constrained
    state.py      the optimiser and its history, saved after every generation: resume after a kill
    outputs.py    best_scene.toml, history.csv, the convergence plot, the held-out table
    __main__.py   the command line and the generation loop
"""
