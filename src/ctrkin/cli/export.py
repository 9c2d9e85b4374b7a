"""`ctrkin export`: write a trained model as ONNX (normalisation included).

    ctrkin export models/fk --out fk.onnx

The ONNX input "window" is (B, IB, F) raw features (oldest step first; see the file's metadata
ctrkin.input_names), the output (B, O) is in mm / deg / unit quaternion.
"""

from __future__ import annotations

import click

from ctrkin.cli.common import InputPath, output_file, overwrite_option, say


@click.command("export", epilog="""\b
Examples:
  ctrkin export models/fk --out fk.onnx""")
@click.argument("model_dir", type=InputPath(file_okay=False))
@click.option("--out", "out_file", required=True, type=click.Path(), help="ONNX file.")
@overwrite_option()
def export_cmd(model_dir: str, out_file: str, overwrite: bool) -> None:
    """Export MODEL_DIR (from `ctrkin train`) to an ONNX file (written atomically)."""
    from ctrkin.inference import Kinematics, export_onnx

    output_file(out_file, "ONNX model", overwrite, inputs=[model_dir])
    kin = Kinematics.load(model_dir)
    path = export_onnx(kin, out_file)
    say(f"wrote {path}: input window (batch, {kin.ib}, {kin.layout.n_inputs}) "
        f"{list(kin.layout.input_names)} -> output {list(kin.layout.output_names)}")
