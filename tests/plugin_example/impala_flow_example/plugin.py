"""The plugin module named by the ``impala_flow`` entry point ``example``.

The engine calls :func:`impala_flow_register` once per run with a fresh registry; every
class added here becomes ``example.<ClassName>`` in YAML graphs.
"""

from __future__ import annotations

from impala_flow.plugins import Registry, hookimpl

from .components import Counter, CsvWriter, MovingAverage, Threshold


@hookimpl
def impala_flow_register(registry: Registry) -> None:
    for cls in (Counter, MovingAverage, Threshold, CsvWriter):
        registry.add_component(cls)
