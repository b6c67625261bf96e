"""Batches of runs: sweep files expanded into locksteps, run on local workers or a Dask cluster.

    python -m bwr_twin.batch SWEEP --out DIR [--workers N | --scheduler tcp://HOST:PORT]
"""

from bwr_twin.batch.cli import BatchLock, main, plan_locksteps

__all__ = ["BatchLock", "main", "plan_locksteps"]
