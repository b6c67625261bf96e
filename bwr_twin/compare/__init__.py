"""Controllers side by side: the same path, the same disturbance seeds, one table and overlaid plots
(`python -m bwr_twin.compare`)."""
