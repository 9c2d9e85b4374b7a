"""The one output rule: an existing output is replaced only with --overwrite (exit 1 otherwise)."""

from __future__ import annotations

from click.testing import CliRunner

from ctrkin.cli.main import cli


def test_collect_refuses_existing_output_without_overwrite(tmp_path) -> None:
    runner = CliRunner()
    out = tmp_path / "sq"
    args = ["collect", "--protocol", "square", "--out", str(out)]
    assert runner.invoke(cli, args).exit_code == 0
    before = (out / "targets.csv").read_bytes()
    res = runner.invoke(cli, [*args, "--seed", "5"])
    assert res.exit_code == 1 and f"{out} exists; pass --overwrite" in res.output
    assert (out / "targets.csv").read_bytes() == before
    res = runner.invoke(cli, [*args, "--seed", "5", "--overwrite"])
    assert res.exit_code == 0, res.output
    assert (out / "targets.csv").read_bytes() != before


def test_an_empty_folder_is_not_output(tmp_path) -> None:
    out = tmp_path / "empty"
    out.mkdir()
    res = CliRunner().invoke(cli, ["collect", "--protocol", "triangle", "--out", str(out)])
    assert res.exit_code == 0, res.output


def test_usage_errors_come_before_the_output_check(tmp_path) -> None:
    (tmp_path / "x").mkdir()
    (tmp_path / "x" / "keep.txt").write_text("mine")
    res = CliRunner().invoke(cli, ["sweep", "--translations", "4,x", "--out", str(tmp_path / "x")])
    assert res.exit_code == 2 and "--translations" in res.output


def test_sweep_and_train_refuse_a_folder_that_is_not_theirs(tmp_path) -> None:
    """A folder ctrkin did not write is refused with or without --overwrite (issue 27: --overwrite
    replaces only a ctrkin output of the same kind), and the message does not suggest --overwrite."""
    runner = CliRunner()
    folder = tmp_path / "mine"
    folder.mkdir()
    (folder / "notes.txt").write_text("keep me")
    data = tmp_path / "data"
    assert runner.invoke(cli, ["collect", "--protocol", "arbitrary", "--out", str(data)],
                         env={"CTRKIN_NO_PROGRESS": "1"}).exit_code == 0
    for flags in ([], ["--overwrite"]):
        res = runner.invoke(cli, ["sweep", "--translations", "4", "--step", "90", "--out", str(folder),
                                  *flags])
        assert res.exit_code == 1 and "is not a ctrkin output" in res.output, res.output
        res = runner.invoke(cli, ["train", "--task", "fk", "--data", str(data), "--out", str(folder),
                                  *flags])
        assert res.exit_code == 1 and "is not a ctrkin output" in res.output, res.output
        assert "pass --overwrite" not in res.output
    assert sorted(p.name for p in folder.iterdir()) == ["notes.txt"]
    assert (folder / "notes.txt").read_text() == "keep me"


def test_every_writing_command_has_overwrite() -> None:
    runner = CliRunner()
    for path in (["dataset", "import"], ["collect"], ["sweep"], ["train"], ["predict"], ["export"],
                 ["calibrate"], ["evaluate"]):
        res = runner.invoke(cli, [*path, "--help"])
        assert res.exit_code == 0 and "--overwrite" in res.output, path
        assert "--force" not in res.output, path
