"""The layers of the package, lowest first: a module imports only from its own sub-package (or,
at the top level, itself) and from lower layers, never up and never sideways to another unit of
its own layer. tests/test_layers.py holds every import of the package to this order.

A unit is a sub-package ("sim") or a top-level module ("units"); "bwr_twin" is the package's own
__init__.py.
"""

LAYERS: tuple[tuple[str, ...], ...] = (
    ("errors",),  # the exceptions every layer raises, and the exit status they give
    # small helpers: units, numbers, text files, signal names, the CLI's parts, shipped files, output marks,
    # OPC UA's building blocks
    ("units", "values", "textfile", "signals", "progress", "arguments", "exposure", "shipped", "ownership", "streams",
     "layers", "opcua"),
    ("arrays", "tomlfile"),  # what the files a user gives hold: arrays and rows checked before they are believed, TOML
    ("model",),  # the machine from its MJCF: kinematics, dynamics, collision shapes, instruments, scanners
    ("drawing",),  # the machine's visual geoms as meshes, posed by its kinematics, in a viser scene
    ("control",),  # the control laws and the fuzzy rule base they read
    ("fis",),  # fuzzy systems in .fis, FCL and FLL, and their conversion to and from control's rule base
    ("config",),  # scene and sweep files, and the plug-in classes they name
    ("pile",),  # the pile's shape: its height grid, the slump of its faces, the wheel's cut
    ("planning",),  # trajectories, bench plans and stacking plans
    ("stockpile",),  # the pile's material: layers, grades, deposits, the stacking and reclaim of a run
    ("sensing", "collision"),  # what instruments and scanners read; anti-collision with pile and neighbour
    ("sim",),  # the plant, encoders and drives, the lockstep loop, one run advanced a period at a time
    ("results",),  # run directories, summaries and figures
    ("run",),  # one scene simulated from the command line
    # the front ends: sweeps, comparison of runs, gym, replay, the OPC UA server, the shadow,
    # calibration from a machine's logs
    ("batch", "compare", "gym", "replay", "serve", "shadow", "calibrate"),
    ("export",),  # FMU, PLC and the Asset Administration Shell, which packs them with what serve serves
    ("tune",),  # gain tuning over batches
    ("bwr_twin",),  # the package itself: what `import bwr_twin` gives
)
