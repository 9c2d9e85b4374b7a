"""`ctrkin predict`: stdout without --out, the format of --out from its extension."""

from __future__ import annotations

import io
import json

import numpy as np
import pandas as pd
import pytest
from click.testing import CliRunner

from ctrkin.cli.main import cli

ENV = {"CTRKIN_NO_PROGRESS": "1"}


@pytest.fixture(scope="module")
def fk_model(tmp_path_factory):
    root = tmp_path_factory.mktemp("predict")
    runner = CliRunner()
    r = runner.invoke(cli, ["collect", "--protocol", "arbitrary", "--workers", "1",
                            "--out", str(root / "data")], env=ENV)
    assert r.exit_code == 0, r.output
    r = runner.invoke(cli, ["train", "--task", "fk", "--model", "lstm_mlp",
                            "--data", str(root / "data"), "--out", str(root / "fk"),
                            "--epochs", "1", "--structure", "L8|D8", "--threads", "1", "--split", "random"],
                      env=ENV)
    assert r.exit_code == 0, r.output
    return root


def test_without_out_a_csv_goes_to_stdout(fk_model) -> None:
    r = CliRunner().invoke(cli, ["predict", str(fk_model / "fk"), "--data", str(fk_model / "data")])
    assert r.exit_code == 0, r.output
    table = pd.read_csv(io.StringIO(r.stdout))
    assert len(table) == 361 and list(table.columns[:3]) == ["sequence_id", "step", "pred_x"]
    assert "361 predictions" in r.stderr


@pytest.mark.parametrize("ext", [".csv", ".parquet", ".json"])
def test_the_extension_chooses_the_format(fk_model, tmp_path, ext) -> None:
    out = tmp_path / f"fk{ext}"
    r = CliRunner().invoke(cli, ["predict", str(fk_model / "fk"), "--data", str(fk_model / "data"),
                                 "--out", str(out)])
    assert r.exit_code == 0, r.output
    if ext == ".csv":
        table = pd.read_csv(out)
    elif ext == ".parquet":
        table = pd.read_parquet(out)         # a CSV would not parse as parquet
    else:
        table = pd.DataFrame(json.loads(out.read_text()))
    assert len(table) == 361 and np.isfinite(table["pred_qy"]).all()


def test_an_unknown_extension_is_a_usage_error(fk_model, tmp_path) -> None:
    r = CliRunner().invoke(cli, ["predict", str(fk_model / "fk"), "--data", str(fk_model / "data"),
                                 "--out", str(tmp_path / "fk.xlsx")])
    assert r.exit_code == 2 and ".parquet" in r.output
    assert not (tmp_path / "fk.xlsx").exists()
