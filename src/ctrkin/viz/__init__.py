"""Plots (matplotlib, Agg backend): sweeps, comparisons, training curves."""
