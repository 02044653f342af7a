"""DATMO plugin (seed 1 §4.3): Doppler mover detection and multi-target tracking.

Components (registered by :mod:`impala_tracking.plugin`): ``tracking.MoverDetector`` and
``tracking.Tracker``. Message type: :class:`MoverDetections`.
"""
