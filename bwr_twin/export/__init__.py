"""The twin's controllers leave the twin: `python -m bwr_twin.export plc SCENE --out DIR`."""
