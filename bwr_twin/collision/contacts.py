"""Each run's contacts, as metrics.json records them (docs/contracts.md): an event per contact,
with its start, its end and its greatest depth with when.

The pile monitor (shapes against the pile) and the machines monitor (pairs of shapes of two
machines) keep the same events, each over its own items.
"""

from __future__ import annotations

import numpy as np


class Contacts:
    """The contact events of `runs` runs over `items` shapes or pairs.

    Attributes:
        open: (runs, items) each item's event under way (an index into its run's events), or -1.
    """

    def __init__(self, runs: int, items: int):
        self.open = np.full((runs, items), -1, dtype=np.int64)
        self._events: list[list[dict]] = [[] for _ in range(runs)]

    def record(self, run: int, item: int, touching: bool, depth: float, time: float, bodies: list[str]) -> None:
        """At `time` (s), an item of `run` `touching` by `depth` (m) opens or deepens its contact
        between `bodies`; one no longer touching closes it."""
        events, index = self._events[run], self.open[run, item]
        if not touching:
            events[index]["end_s"] = time
            self.open[run, item] = -1
        elif index < 0:
            self.open[run, item] = len(events)
            events.append({"time_s": time, "end_s": None, "bodies": bodies, "depth_m": depth, "depth_time_s": time})
        elif depth > events[index]["depth_m"]:
            events[index]["depth_m"], events[index]["depth_time_s"] = depth, time

    def events(self, run: int) -> list[dict]:
        """A copy of `run`'s events, oldest first."""
        return [dict(e) for e in self._events[run]]
