"""impala-flow-example-plugin: a small third-party plugin for impala-flow.

The components live in :mod:`impala_flow_example.components`; the plugin module that
registers them (the ``impala_flow`` entry point) is :mod:`impala_flow_example.plugin`.
"""

from .components import Counter, CsvWriter, MovingAverage, Threshold

__all__ = ["Counter", "MovingAverage", "Threshold", "CsvWriter"]
