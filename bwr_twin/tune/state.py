"""The tuner's state, saved whole after every generation, so that a tuning killed at any moment
continues from its last completed generation and ends where it would have ended uninterrupted.

CMA-ES draws its samples from numpy's global generator: its state is saved with the strategy.
"""

from __future__ import annotations

import pickle
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from bwr_twin.errors import BwrError
from bwr_twin.ownership import write_atomically

STATE_FILE = "tuner_state.pkl"


@dataclass
class TunerState:
    strategy: Any  # cma.CMAEvolutionStrategy, or a ScalarSearch for one parameter
    normalisers: dict[str, list[float]]  # metric -> per-axis value at the start
    generation: int = 0  # completed generations (0: the start point alone)
    evaluations: int = 0  # candidates evaluated, the start point included
    elapsed: float = 0.0  # s spent tuning, over every invocation
    history: list[dict] = field(default_factory=list)  # one row per candidate, history.csv's
    best: dict | None = None  # {"values", "objective", "generation", "candidate"} of the best feasible
    finished: str = ""  # why the tuning stopped, once it has
    random_state: Any = None  # numpy's global generator after the last generation

    def save(self, folder: Path) -> None:
        self.random_state = np.random.get_state()
        write_atomically(folder / STATE_FILE, lambda partial: partial.write_bytes(pickle.dumps(self)),
                         owner=folder)

    @classmethod
    def load(cls, folder: Path) -> TunerState | None:
        """The saved state, with numpy's generator put back as it was; None if there is none."""
        path = folder / STATE_FILE
        if not path.exists():
            return None
        try:
            state = pickle.loads(path.read_bytes())
            if not isinstance(state, TunerState):
                raise TypeError(f"it holds a {type(state).__name__}, not a tuner's state")
            np.random.set_state(state.random_state)
        except Exception as exc:  # unpickling damaged bytes may raise any exception
            why = exc.strerror if isinstance(exc, OSError) else str(exc) or type(exc).__name__
            raise BwrError(f"{path}: damaged, not a state this tuner saved ({why}); remove it to start the "
                           "tuning afresh, or choose another --out") from None
        return state
