"""The machine: the MJCF model contract, kinematics and frames, and every edit made before compiling."""
