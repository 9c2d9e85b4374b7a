"""Every experiment of a reproduction, in the order it runs and the report reads (the typed table of
ctrkin.evaluation.table): the FK comparison and experiments (Fig. 5, 10), what the training learned
(Fig. 6, 9), the IK experiments (Fig. 11, 12), the input-buffer and structure grids (Tables II, III)
and timing. Each module declares its own beside its code; a new experiments module is one more entry
here."""

from __future__ import annotations

from ctrkin.evaluation import experiments_fk, experiments_ik, experiments_training, grids
from ctrkin.evaluation.table import Experiment, Figure

EXPERIMENTS: tuple[Experiment, ...] = (*experiments_fk.EXPERIMENTS, *experiments_training.EXPERIMENTS,
                                       *experiments_ik.EXPERIMENTS, *grids.EXPERIMENTS)
FIGURES: tuple[Figure, ...] = tuple(f for e in EXPERIMENTS for f in e.figures)   # the report's reading order
