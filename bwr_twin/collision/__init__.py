"""Collision geometry: the machine's shapes from its MJCF, and their clearance to the pile as each
run has dug it (docs/anticollision.md)."""
