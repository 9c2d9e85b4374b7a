"""`ctrkin export`: write a trained model as ONNX (normalisation included).

    ctrkin export models/fk --out fk.onnx
    ctrkin export models/fk_branch --out fk.onnx --allow-downgrade    # its network, learned gate

The ONNX input "window" is (B, IB, F) raw features (oldest step first; see the file's metadata
ctrkin.input_names), the output (B, O) is in mm / deg / unit quaternion; a snap-aware FK adds the
input "state" (B,) (the branch state, 0.5 at a sequence start) and the output "state_out", a model
with an outer-tube lag the input "outer_lag_deg" (B,); the summary lists every input and output.

A model whose ONNX graph would compute less than `ctrkin predict` is refused (exit 1) with what
would be lost: a snap-aware FK with its fold gate (the graph has the learned gate only) and a
refined IK (the refinement runs outside the network); `--allow-downgrade` exports their network
alone. A follow IK (follow_mlp) cannot be exported (its joint state loops outside the network).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import click

from ctrkin.cli.common import output_file, overwrite_option, say
from ctrkin.cli.from_config import config_options, option_help


@dataclass(frozen=True, kw_only=True)
class ExportConfig:
    """What `ctrkin export` writes (one option, or the argument, per field)."""

    model_dir: str = field(metadata=option_help("A model folder (ctrkin train).", path="folder",
                                                argument=True))
    out: str = field(metadata=option_help("ONNX file.", path="out"))
    allow_downgrade: bool = field(default=False, metadata=option_help(
        "Export the network alone where the graph cannot hold all that predict runs (a snap-aware FK's "
        "fold gate, a refined IK's refinement); refused without it.", flag=True))


@click.command("export", epilog="""\b
Examples:
  ctrkin export models/fk --out fk.onnx
  ctrkin export models/fk_branch --out fk_learned_gate.onnx --allow-downgrade""")
@config_options(ExportConfig)
@overwrite_option()
def export_cmd(overwrite: bool, **settings: Any) -> None:
    """Export MODEL_DIR (from `ctrkin train`) to an ONNX file (written atomically)."""
    from ctrkin.inference import Kinematics, export_onnx
    from ctrkin.inference.onnx_export import graph_signature

    cfg = ExportConfig(**settings)
    model_dir, out_file = cfg.model_dir, cfg.out
    output_file(out_file, "ONNX model", overwrite, inputs=[model_dir])
    kin = Kinematics.load(model_dir)
    downgrade = kin.predictor.export_downgrade()
    path = export_onnx(kin, out_file, allow_downgrade=cfg.allow_downgrade)
    inputs, outputs = graph_signature(path)
    say(f"wrote {path}: inputs {', '.join(inputs)} -> outputs {', '.join(outputs)}; window features "
        f"{list(kin.layout.input_names)}, output {list(kin.layout.output_names)}")
    if downgrade is not None:
        say(f"warning: exported the network alone (--allow-downgrade): {downgrade}")
