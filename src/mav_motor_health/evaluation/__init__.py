"""Scoring diagnoses against the simulator's ground truth."""
