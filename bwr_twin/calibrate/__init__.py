"""Calibration of a machine's MJCF from its own records, on MuJoCo's system identification
(`mujoco.sysid`): the log read and checked (`log`; from a run directory or a historian's CSV,
`reading`, `historian`), the parameters a log can fit with their
bounds (`parameters`), the fit over windows started from the measured state (`fit`), the
engineer's MJCF changed in place (`mjcf_edit`), and a test motion to record (`plan`).
"""
