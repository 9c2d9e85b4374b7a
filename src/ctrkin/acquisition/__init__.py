"""Acquisition: joint trajectories of the paper's protocols and recording them into datasets."""
