"""Export a scene's controller for the engineer's tools.

    python -m bwr_twin.export plc pid_paper --out plc/pid_paper
    python -m bwr_twin.export fmu pid_paper --out reclaimer.fmu
    python -m bwr_twin.export aas pid_paper --out reclaimer.aasx [--calibration DIR]
    python -m bwr_twin.export aas --check reclaimer.aasx

`plc` writes the controller as IEC 61131-3 Structured Text into DIR (bwr_twin.export.plc). DIR must
not exist, or be an export the twin wrote and --overwrite be given. `fmu` writes one run of the
scene as a co-simulation FMU: native (C and MuJoCo, FMI 2.0 or, with --fmi 3, 3.0;
bwr_twin.export.native_fmu) where the scene is a path, else the Python FMU (FMI 2.0,
bwr_twin.export.fmu), saying which and why; an existing one is replaced only with --overwrite, and
only if the twin wrote it. --overwrite replaces only what the twin wrote, unchanged
since (its manifest, bwr_twin.ownership): a file of the engineer's in DIR, or one edited, is named
and refused. `aas` writes the machine as an Asset Administration Shell package holding the FMU, the
MJCF, the PLC package and the NodeSet2 (bwr_twin.export.aas, docs/aas.md), replaced as an FMU is;
`aas --check` checks a package and prints one line per problem (status 1 if any).
A bad scene exits with status 2 and one line on stderr, and nothing is written.
"""

from __future__ import annotations

import sys
from pathlib import Path

from bwr_twin.arguments import CommandParser
from bwr_twin.errors import exit_status, leave
from bwr_twin.sim.budget import FORCE_HELP


def main(argv: list[str] | None = None) -> int:
    parser = CommandParser(prog="python -m bwr_twin.export", description=__doc__.split("\n\n")[0])
    commands = parser.add_subparsers(dest="command", required=True)
    plc = commands.add_parser("plc", help="the controller as IEC 61131-3 Structured Text")
    plc.add_argument("scene", help="scene TOML file, or a shipped scene's name, e.g. pid_paper")
    plc.add_argument("--out", required=True, type=Path, help="output directory (must not exist)")
    plc.add_argument("--real", action="store_true", help="REAL (32-bit) instead of LREAL, for PLCs without LREAL")
    plc.add_argument("--grid", type=int, help="grid points per input of a fuzzy control surface's table (the "
                     "twin's by default, so that the block equals it); the README states the error bound")
    plc.add_argument("--fuzzy", choices=("table", "rules"), default="table",
                     help="a fuzzy controller's fuzzy part as its control surface's table (default), or inferred "
                     "rule by rule each cycle as skfuzzy does (no table; the README states its cost)")
    plc.add_argument("--overwrite", action="store_true", help="replace DIR, an export the twin wrote")
    fmu = commands.add_parser("fmu", help="one run of the scene as a co-simulation FMU")
    fmu.add_argument("scene", help="scene TOML file, or a shipped scene's name, e.g. pid_paper")
    fmu.add_argument("--out", required=True, type=Path, help="the .fmu file to write (must not exist)")
    fmu.add_argument("--fmi", type=int, choices=(2, 3), default=2, help="FMI version of the native FMU (default 2)")
    fmu.add_argument("--overwrite", action="store_true", help="replace FILE, an FMU the twin wrote")
    fmu.add_argument("--force", action="store_true", help=FORCE_HELP)
    aas = commands.add_parser("aas", help="the machine as an Asset Administration Shell (AASX) package")
    aas.add_argument("scene", nargs="?", help="scene TOML file, or a shipped scene's name, e.g. pid_paper")
    aas.add_argument("--out", type=Path, help="the .aasx file to write (must not exist)")
    aas.add_argument("--overwrite", action="store_true", help="replace FILE, a package the twin wrote")
    aas.add_argument("--calibration", type=Path, metavar="DIR", help="a calibration report's folder (holding "
                     "calibration.json) to pack with the models; without it the package has none")
    aas.add_argument("--check", type=Path, metavar="FILE.aasx", help="check a package instead of writing one")
    aas.add_argument("--force", action="store_true", help=FORCE_HELP)
    args = parser.parse_args(argv)
    return exit_status(lambda: {"plc": _plc, "fmu": _fmu, "aas": _aas}[args.command](args))


def _plc(args) -> int:
    from bwr_twin.config.scene import load_scene
    from bwr_twin.export.plc import export_plc
    from bwr_twin.shipped import find_scene

    scene = load_scene(find_scene(args.scene))
    for path in export_plc(scene, args.out, real=args.real, grid=args.grid, fuzzy=args.fuzzy,
                           overwrite=args.overwrite):
        print(path)
    return 0


def _fmu(args) -> int:
    from bwr_twin.config.scene import load_scene
    from bwr_twin.export.scene_fmu import export_scene_fmu
    from bwr_twin.shipped import find_scene
    from bwr_twin.sim.budget import check_scenes

    scene = load_scene(find_scene(args.scene))
    check_scenes([scene], where=scene.path, out_dir=args.out.parent, force=args.force)  # the run the FMU will make
    out, obstacle = export_scene_fmu(scene, args.out, fmi=args.fmi, overwrite=args.overwrite)
    if obstacle is None:
        print(f"native FMU, FMI {args.fmi}.0: C and MuJoCo's C library, no Python inside")
    else:
        print(f"Python FMU (pythonfmu), FMI 2.0: {obstacle}; it needs Python with bwr_twin where it runs (docs/fmu.md)")
    print(out)
    return 0


def _aas(args) -> int:
    from bwr_twin.errors import BwrError

    if args.check is not None:
        if args.scene is not None or args.out is not None or args.calibration is not None:
            raise BwrError("aas --check FILE.aasx checks a package: give no SCENE, --out or --calibration")
        from bwr_twin.export.aas import check_aas

        problems = check_aas(args.check)
        for line in problems:
            print(line, file=sys.stderr)
        if not problems:
            print(f"{args.check}: passes basyx-compliance-tool and the IDTA templates' required elements")
        return 1 if problems else 0
    if args.scene is None or args.out is None:
        raise BwrError("aas needs SCENE and --out FILE.aasx (or --check FILE.aasx)")
    from bwr_twin.config.scene import load_scene
    from bwr_twin.export.aas import export_aas
    from bwr_twin.shipped import find_scene
    from bwr_twin.sim.budget import check_scenes

    scene = load_scene(find_scene(args.scene))
    check_scenes([scene], where=scene.path, out_dir=args.out.parent, force=args.force)  # the FMU's run
    print(export_aas(scene, args.out, overwrite=args.overwrite, calibration=args.calibration))
    return 0


if __name__ == "__main__":
    leave(main())
