"""Evaluation: metrics, the TCM baseline, the paper's experiments and the reproduction report."""
