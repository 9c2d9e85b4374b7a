"""Exceptions that tell the user what to change.

Every error ctrkin raises on purpose is a `CtrkinError`; the command line turns one into a single
line on stderr and exit status 1. The subclasses also derive from the built-in exception a caller
would expect (ValueError, RuntimeError), so generic handlers keep working.
"""


class CtrkinError(Exception):
    """Base class of every error ctrkin raises on purpose: catch it to handle them all."""


class RobotDescriptionError(CtrkinError, ValueError):
    """A robot or tube description is not physical or not well formed (a TOML file, a `Tube`)."""


class JointError(CtrkinError, ValueError):
    """A joint vector violates the robot's joint convention or limits (docs/design.md: Conventions).

    Raised by `Robot.check_joints` and everything that takes joints: the message names the violated
    condition and the values.
    """


class ConvergenceError(CtrkinError, RuntimeError):
    """The mechanics solver found no equilibrium, or a configuration would need unbounded work."""


class DatasetError(CtrkinError, ValueError):
    """A dataset or log file is malformed, incomplete or from another robot (the message names the
    file, and where it can, the line and column)."""


class ModelError(CtrkinError, ValueError):
    """A model folder is corrupt, or does not fit the data or robot it is used with."""


class OutputError(CtrkinError, ValueError):
    """An output that ctrkin refuses to write or replace (not its own, an input, a protected place)."""
