"""Entry point of the radar plugin: registers the radar sources and the front-end components."""

from impala_flow.plugins import hookimpl


@hookimpl
def impala_flow_register(registry):  # type: ignore[no-untyped-def]
    pass  # filled as the simulator source lands (issue 4)
