"""Issue 23 item 6: `reproduce`'s closing lines name the models their figures are from (the
recommended snap-aware FK and follow IK, not "LSTM-MLP") and give joint errors in their own units."""

from __future__ import annotations

import json
from pathlib import Path

from ctrkin.cli.reproduce import headlines

RESULTS = Path(__file__).parents[1] / "evaluation" / "tiny_results.json"


def test_headlines_name_the_recommended_models_and_units():
    results = json.loads(RESULTS.read_text())
    fk, ik = headlines(results["fk"], results["ik"])
    assert fk.startswith("FK, snap-aware LSTM-MLP (lstm_mlp_branch): position 7.341 mm, orientation "
                         "22.970 deg")
    assert "the paper's LSTM-MLP: 0.69 mm, 0.16 deg" in fk
    assert ik.startswith("IK, follow IK (follow_mlp): tip reached 21.590 mm")
    assert "β 8.405 mm, α 157.7 deg" in ik and "mm / " not in ik + fk
