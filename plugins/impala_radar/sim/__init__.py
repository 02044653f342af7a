"""Radar simulator: vehicle trajectories, proprioceptive sensors, worlds."""
