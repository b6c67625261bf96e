"""The project's one error hierarchy.

Every message names what was wrong (a file, a key, a via point, an axis), the limit it broke
and the value it had, so that the command line can print it as one line and exit.
"""


class BwrError(Exception):
    """Base class of every error this package raises on purpose."""


class ModelError(BwrError):
    """An MJCF file is missing, does not compile or breaks the model contract."""


class UnreachableError(BwrError):
    """A bucket wheel centre position that no joint configuration reaches."""


class EnvelopeError(BwrError):
    """A joint value outside the machine's operating envelope."""


class SceneError(BwrError):
    """A scene or sweep file that cannot be read or breaks a rule."""


class SimulationError(BwrError):
    """A run that diverged or that MuJoCo warned about."""
