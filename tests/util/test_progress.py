"""Progress off a terminal: a few quarter-mark lines and a heartbeat, not one line per update."""

from __future__ import annotations

import gc
import re
import threading
import time

from ctrkin.util.progress import QuarterLog, progress_bar

# "desc: n/total (what, elapsed[, ~left])[  postfix]"
LINE = re.compile(r"^(?P<desc>.+?): (?P<count>\d+(?:/\d+)?) "
                  r"\((?P<what>[^,]+), (?P<time>[^)]+)\)(?P<post>.*)$")


def _lines(capsys) -> list[re.Match]:
    lines = capsys.readouterr().err.strip().splitlines()
    matches = [LINE.match(ln) for ln in lines]
    assert all(matches), lines
    return matches  # type: ignore[return-value]


def test_quarter_log_prints_four_lines(capsys):
    with QuarterLog(total=500, desc="train") as bar:
        for _ in range(500):
            bar.update(1)
            bar.set_postfix(val=0.1)
    lines = _lines(capsys)
    assert [(m["count"], m["what"]) for m in lines] == [
        ("125/500", "25%"), ("250/500", "50%"), ("375/500", "75%"), ("500/500", "100%")]
    assert lines[0]["desc"] == "train" and lines[0]["post"] == "  val=0.1"
    assert "left" in lines[0]["time"] and "left" not in lines[-1]["time"]   # time left at the rate


def test_progress_bar_off_a_terminal_is_a_quarter_log(monkeypatch):
    monkeypatch.delenv("CTRKIN_NO_PROGRESS", raising=False)
    bar = progress_bar(total=10, desc="x")      # pytest captures stderr: not a terminal
    assert isinstance(bar, QuarterLog)
    bar.close()


def test_quarter_log_reports_an_early_stop_once(capsys):
    bar = QuarterLog(total=500, desc="train")
    for _ in range(140):
        bar.update(1)
    bar.close()
    bar.close()
    lines = _lines(capsys)
    assert [(m["count"], m["what"]) for m in lines] == [("125/500", "25%"), ("140/500", "stopped")]


def test_an_update_across_several_marks_prints_one_line(capsys):
    """`collect --protocol arbitrary` records its one 361-step segment in one update: it printed
    '361/361 (25%)', '361/361 (50%)', ... (issue 23)."""
    with QuarterLog(total=361, desc="collect arbitrary") as bar:
        bar.update(361)
    assert [(m["count"], m["what"]) for m in _lines(capsys)] == [("361/361", "100%")]
    with QuarterLog(total=100, desc="x") as bar:
        bar.update(10)
        bar.update(60)      # crosses 25 % and 50 %
    assert [(m["count"], m["what"]) for m in _lines(capsys)] == [("70/100", "50%")]


def test_heartbeat_while_a_unit_of_work_takes_long(capsys):
    """A log shows at least once per heartbeat interval that the work goes on (a 13-minute training
    was silent until 25 % of its epochs)."""
    with QuarterLog(total=500, desc="train", heartbeat_s=0.05) as bar:
        time.sleep(0.3)                   # one epoch that takes six intervals
        bar.update(1)
    lines = _lines(capsys)
    assert len(lines) >= 3
    assert {m["what"] for m in lines} == {"running", "stopped"}
    assert all(m["count"].endswith("/500") for m in lines)


def test_heartbeat_resets_after_a_line_and_stops_on_close(capsys):
    bar = QuarterLog(total=4, desc="x", heartbeat_s=0.2)
    for _ in range(4):                    # every update prints a quarter line: no heartbeat due
        time.sleep(0.08)
        bar.update(1)
    bar.close()
    time.sleep(0.3)
    assert [m["what"] for m in _lines(capsys)] == ["25%", "50%", "75%", "100%"]


def test_an_unclosed_reporter_is_collected_and_its_thread_ends():
    bar = QuarterLog(total=10, desc="forgotten", heartbeat_s=0.02)
    thread = bar._thread
    assert thread is not None and thread.is_alive()
    del bar
    gc.collect()
    thread.join(timeout=2.0)
    assert not thread.is_alive()
    assert not any(t.name == "ctrkin-progress-forgotten" for t in threading.enumerate())
