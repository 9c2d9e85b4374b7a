"""`ctrkin train`: learn forward (joints -> tip pose) or inverse (tip poses -> joints) kinematics.

    ctrkin train --task fk --data data/paper_full --out models/fk              # paper default model
    ctrkin train --task ik --data data/paper_full --out models/ik
    ctrkin train --task fk --model mlp --ib 3 --data data/quick --out models/fk_mlp
    ctrkin train --task fk --model lstm_mlp --structure S3 --ib 3 --data data/quick --out models/s3
    ctrkin train --task fk --model lstm_mlp_no_delta --data data/quick --out models/no_delta   # Fig. 5b
    ctrkin train --task fk --model lstm_mlp_branch --epochs 80 --patience 80 --batch-size 256 \
        --lr 2e-3 --lr-schedule cosine --data data/quick --out models/fk_branch   # snap-aware FK
    ctrkin train --task fk --batch-size 1024 --lr 5.66e-3 --val-smoothing 0.5 --threads 1 \
        --data data/quick --out models/fk_fast     # ~5x the samples/s of batch 32 (lr: sqrt rule)

Running the same command again resumes from the last checkpoint in --out (or raise --max-epochs to
continue a finished run); --overwrite starts over. Models: see `ctrkin train --list-models`.
"""

from __future__ import annotations

import json
from pathlib import Path

import click

from ctrkin.cli.common import check_output, emit_json, json_option, log_line, say
from ctrkin.data import Dataset


def _list_models(ctx: click.Context, _param: click.Parameter, value: bool) -> None:
    if not value or ctx.resilient_parsing:
        return
    from ctrkin.models import MODELS, STRUCTURES

    for name, e in MODELS.items():
        click.echo(f"{name:20s} {e.description}")
    click.echo("structures (lstm_mlp --structure): " + ", ".join(f"{k}={v}" for k, v in STRUCTURES.items()))
    ctx.exit()


def _check_model_folder(out: Path, overwrite: bool) -> None:
    """The output rule for a model folder: the same setup resumes, another model needs --overwrite
    (ctrkin.training checks both); anything else in --out is refused here unless --overwrite."""
    from ctrkin.models.store import CONFIG
    from ctrkin.training.loop import CHECKPOINT

    if not ((out / CONFIG).is_file() or (out / CHECKPOINT).is_file()):
        check_output(out, overwrite)


@click.command("train", epilog="""\b
Examples:
  ctrkin train --task fk --data data/paper --out models/fk
  ctrkin train --task ik --model follow_mlp --data data/paper --out models/ik_follow
  ctrkin train --list-models
  ctrkin train --task fk --data data/paper --out models/fk --json > fk_metrics.json""")
@click.option("--list-models", is_flag=True, expose_value=False, is_eager=True, callback=_list_models,
              help="List the model registry and exit.")
@click.option("--task", type=click.Choice(["fk", "ik"]), required=True, help="Forward or inverse kinematics.")
@click.option("--data", "data_dir", required=True, type=click.Path(exists=True, file_okay=False),
              help="Dataset folder (data.parquet + meta.json).")
@click.option("--out", "out_dir", required=True, type=click.Path(file_okay=False), help="Model folder.")
@click.option("--model", default="lstm_mlp", show_default=True, help="Registry name (--list-models).")
@click.option("--structure", default=None, help="LSTM-MLP/LSTM/MLP structure: paper, S1..S5 or 'L128|D64'.")
@click.option("--option", "options", multiple=True, metavar="KEY=VALUE",
              help="Other model options, e.g. channels=32 (cnn/tcn), width=64 (resnet).")
@click.option("--ib", default=2, show_default=True, help="Input buffer: current + IB-1 previous steps.")
@click.option("--no-delta", is_flag=True, help="Drop the directional feature Δα0 (IK: the pose deltas).")
@click.option("--angles", type=click.Choice(["minmax", "sincos"]), default="minmax", show_default=True,
              help="FK angle encoding: min-max of unwrapped degrees (paper) or sin/cos.")
@click.option("--output-activation", type=click.Choice(["relu", "linear"]), default="relu", show_default=True,
              help="Output layer activation (paper eq. 7: relu).")
@click.option("--pose", "pose_source", type=click.Choice(["measured", "true"]), default="measured",
              show_default=True, help="Pose columns to learn from (true: virtual-robot ground truth).")
@click.option("--split", type=click.Choice(["dataset", "sequence", "random"]), default="dataset",
              show_default=True, help="dataset: its saved split, else by sequence; random: paper 70:15:15.")
@click.option("--epochs", "max_epochs", default=500, show_default=True, help="Maximum epochs.")
@click.option("--patience", default=20, show_default=True, help="Early stopping patience (epochs).")
@click.option("--batch-size", default=32, show_default=True)
@click.option("--lr", default=1e-3, show_default=True)
@click.option("--lr-schedule", type=click.Choice(["constant", "cosine"]), default="constant",
              show_default=True, help="constant (paper) or cosine decay to lr/50 over --epochs.")
@click.option("--loop", type=click.Choice(["epoch", "batch"]), default="epoch", show_default=True,
              help="epoch: one gather per epoch, fused Adam; batch: the loop before issue 11.")
@click.option("--val-smoothing", default=0.0, show_default=True,
              help="Early stopping on a moving average of the val loss with this factor (0: raw).")
@click.option("--max-seconds", default=None, type=float, help="Training-time budget (s).")
@click.option("--seed", default=0, show_default=True)
@click.option("--threads", default=2, show_default=True, help="torch CPU threads.")
@click.option("--overwrite", is_flag=True, help="Start over even if --out holds a checkpoint or another "
              "model; replace --out if it is a folder that is not a model.")
@json_option
def train_cmd(task: str, data_dir: str, out_dir: str, model: str, structure: str | None,
              options: tuple[str, ...], ib: int, no_delta: bool, angles: str, output_activation: str,
              pose_source: str, split: str, max_epochs: int, patience: int, batch_size: int, lr: float,
              lr_schedule: str, loop: str, val_smoothing: float, max_seconds: float | None, seed: int,
              threads: int, overwrite: bool, as_json: bool) -> None:
    """Train a history-aware kinematics model (paper LSTM-MLP by default) and save it to --out."""
    from ctrkin.training import TrainConfig, train

    opts: dict[str, object] = {}
    for item in options:
        if "=" not in item:
            raise click.BadParameter(f"--option must be KEY=VALUE, got {item!r}")
        k, v = item.split("=", 1)
        opts[k] = int(v) if v.lstrip("-").isdigit() else v
    if structure is not None:
        opts["structure"] = structure
    cfg = TrainConfig(task=task, model=model, options=opts, ib=ib, delta=not no_delta, angle_encoding=angles,
                      output_activation=output_activation, pose_source=pose_source, split=split,
                      max_epochs=max_epochs, patience=patience, batch_size=batch_size, lr=lr,
                      lr_schedule=lr_schedule, loop=loop, val_smoothing=val_smoothing,
                      max_seconds=max_seconds, seed=seed, threads=threads)
    _check_model_folder(Path(out_dir), overwrite)
    ds = Dataset.load(data_dir)
    ds.meta.setdefault("path", data_dir)
    res = train(ds, cfg, out_dir, overwrite=overwrite, log=log_line)
    tr = res.metrics["training"]
    say(f"trained {tr['epochs']} epochs (best {tr['best_epoch']}, val loss {tr['best_val_loss']:.4g}) "
        f"in {tr['seconds']:.1f} s; model in {res.out}")
    if as_json:
        emit_json({"out": res.out, "task": task, "model": model, **res.metrics})
    else:
        say(json.dumps({k: v for k, v in res.metrics.items() if k in ("val", "test")}, indent=2))
