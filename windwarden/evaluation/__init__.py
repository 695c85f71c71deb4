"""Batch evaluation: plant and supervisor in one process, vectorised over Monte Carlo runs, scored."""
