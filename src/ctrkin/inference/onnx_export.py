"""Export a trained model to ONNX, normalisation included (the graph: ctrkin.models.onnx_graph).

    from ctrkin.inference import Kinematics, export_onnx
    export_onnx(Kinematics.load("models/fk"), "fk.onnx")

Each family says what its graph holds (a snap-aware model's state input, an outer lag input) or why
it has none (the follow IK's joint state loops outside its network). An export never silently
computes less than `predict` does: where the graph would lose part of the model (a snap-aware FK's
fold gate, a refined IK's refinement: Predictor.export_downgrade) it is refused with the reason
unless `allow_downgrade` asks for the network alone.
"""

from __future__ import annotations

from pathlib import Path

from ctrkin.errors import ModelError
from ctrkin.inference.kinematics import Kinematics


def export_onnx(kin: Kinematics, path: str | Path, opset: int = 17, allow_downgrade: bool = False) -> Path:
    """Write `kin` as an ONNX file (dynamic batch size); returns the path. ModelError if the graph
    would lose what `predict` runs (the reason is said) and allow_downgrade is False."""
    check = getattr(kin.predictor, "check_exportable", None)
    if check is not None:              # what cannot be exported at all is said before a downgrade
        check()
    reason = kin.predictor.export_downgrade()
    if reason is not None and not allow_downgrade:
        raise ModelError(f"not exported: {reason}; pass allow_downgrade=True (ctrkin export "
                         "--allow-downgrade) to export the network alone, knowing it computes less")
    out = Path(path)
    kin.predictor.export_onnx(out, opset)
    return out


def graph_signature(path: str | Path) -> tuple[list[str], list[str]]:
    """(inputs, outputs) of an ONNX file, each as 'name (dim, dim, ...)' with symbolic dimensions by
    name (batch) and fixed ones by size."""
    import onnx

    graph = onnx.load(str(path)).graph

    def describe(values: list) -> list[str]:
        out = []
        for v in values:
            dims = [d.dim_param or str(d.dim_value) for d in v.type.tensor_type.shape.dim]
            out.append(f"{v.name} ({', '.join(dims)})")
        return out

    return describe(list(graph.input)), describe(list(graph.output))
