"""MATLAB Fuzzy Logic Toolbox .fis files (type-1 Mamdani): read, write, evaluate, convert, plot.

    system.py      the FuzzySystem data and its checks
    membership.py  MATLAB's membership functions (trimf, trapmf, gaussmf, ...)
    reader.py      .fis text -> FuzzySystem
    writer.py      FuzzySystem -> .fis text, as MATLAB lays it out
    inference.py   Mamdani evaluation as MATLAB's evalfis, vectorised over input rows
    convert.py     FuzzySystem <-> the project's TOML rule base (bwr_twin.control.rulebase), and
                   fis_rule_base: a .fis file as the fuzzy_model controller's rule base
    surface.py     the control surface and membership functions as a picture
    __main__.py    the command line: evaluate, convert, surface

docs/fis.md describes what is supported and what cannot be converted.
"""

from bwr_twin.fis.inference import DEFAULT_POINTS, FisWarning, evaluate
from bwr_twin.fis.reader import parse_fis, read_fis
from bwr_twin.fis.system import FuzzySystem, MembershipFunction, Rule, Variable, check
from bwr_twin.fis.writer import fis_text, write_fis

__all__ = [
    "DEFAULT_POINTS",
    "FisWarning",
    "FuzzySystem",
    "MembershipFunction",
    "Rule",
    "Variable",
    "check",
    "evaluate",
    "fis_text",
    "parse_fis",
    "read_fis",
    "write_fis",
]
