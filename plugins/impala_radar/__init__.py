"""Rotating FMCW radar driver plugin: simulator, sensors and real-scan readers."""
