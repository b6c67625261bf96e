"""The automation's own senses (docs/sensing.md): 2D laser scanners on the machine, read from its
MJCF (`scanner`); rays cast against the pile as each run has dug it (`raycast`); each run's scans
in the loop (`scanning`), with their noise and dropouts from the run's own stream (`noise`); the
pile the automation knows only from them (`survey`); and what a run keeps and writes (`outputs`)."""
