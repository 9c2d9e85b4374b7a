"""The IK workspace check: the old import path of ctrkin.models.workspace (the model folder owns it)."""

from ctrkin.models.workspace import WORKSPACE_FILE, Workspace

__all__ = ["WORKSPACE_FILE", "Workspace"]
