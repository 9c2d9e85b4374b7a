"""Exceptions that tell the user what to change."""


class CtrkinError(Exception):
    """Base class of every error ctrkin raises on purpose."""


class RobotDescriptionError(CtrkinError, ValueError):
    """A robot or tube description is not physical or not well formed."""


class JointError(CtrkinError, ValueError):
    """A joint vector violates the robot's joint convention or limits."""


class ConvergenceError(CtrkinError, RuntimeError):
    """The mechanics solver found no equilibrium."""


class DatasetError(CtrkinError, ValueError):
    """A dataset or log file is malformed, incomplete or from another robot."""


class ModelError(CtrkinError, ValueError):
    """A model file does not fit the data or robot it is used with."""


class OutputError(CtrkinError, ValueError):
    """An output that ctrkin refuses to write or replace (not its own, an input, a protected place)."""
