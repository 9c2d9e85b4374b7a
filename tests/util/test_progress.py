"""Progress off a terminal: a few quarter-mark lines, not one line per update."""

from __future__ import annotations

from ctrkin.util.progress import QuarterLog, progress_bar


def test_quarter_log_prints_four_lines(capsys):
    with QuarterLog(total=500, desc="train") as bar:
        for _ in range(500):
            bar.update(1)
            bar.set_postfix(val=0.1)
    lines = capsys.readouterr().err.strip().splitlines()
    assert len(lines) == 4
    assert lines[0].startswith("train: 125/500 (25%)") and lines[-1].startswith("train: 500/500 (100%)")


def test_progress_bar_off_a_terminal_is_a_quarter_log(monkeypatch):
    monkeypatch.delenv("CTRKIN_NO_PROGRESS", raising=False)
    bar = progress_bar(total=10, desc="x")      # pytest captures stderr: not a terminal
    assert isinstance(bar, QuarterLog)


def test_quarter_log_reports_an_early_stop_once(capsys):
    bar = QuarterLog(total=500, desc="train")
    for _ in range(140):
        bar.update(1)
    bar.close()
    bar.close()
    lines = capsys.readouterr().err.strip().splitlines()
    assert [ln.split(" (")[0] for ln in lines] == ["train: 125/500", "train: 140/500"]
    assert lines[1].endswith("(stopped)")
