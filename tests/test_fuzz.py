"""A CI-sized slice of benchmarks/fuzz.py (issue 9): about 200 seeded inputs over every area, and no
crash, silent wrong answer, hang, data loss or mixed read among them (the last two: issue 27)."""

from __future__ import annotations

import pytest

from tests.benchmark_scripts import load_benchmark


@pytest.mark.slow
def test_fuzz_slice_has_no_crash_silent_or_hang():
    fuzz = load_benchmark("fuzz")
    counts = fuzz.run(scale=0.01, seed=1, log=lambda _m: None)
    assert set(counts) == set(fuzz.AREAS)
    total = {o: sum(c[o] for c in counts.values()) for o in fuzz.OUTCOMES}
    assert sum(total.values()) >= 200
    assert total["clear"] > 0 and total["ok"] > 0          # the slice reaches both sides of the checks
    bad = {a: {o: c[o] for o in fuzz.BAD if c[o]} for a, c in counts.items()}   # lost, mixed too
    assert not any(bad.values()), bad
