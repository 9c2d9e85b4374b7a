"""Loss histories read back from a model folder (Fig. 9)."""

from __future__ import annotations

from ctrkin.training.curves import read_history


def test_read_history_gives_floats_per_epoch_and_nothing_without_a_file(tmp_path) -> None:
    (tmp_path / "history.csv").write_text("epoch,train_loss,val_loss\n1,0.5,0.6\n2,0.25,0.4\n")
    assert read_history(tmp_path) == [{"epoch": 1.0, "train_loss": 0.5, "val_loss": 0.6},
                                      {"epoch": 2.0, "train_loss": 0.25, "val_loss": 0.4}]
    assert read_history(tmp_path / "assembled") == []
