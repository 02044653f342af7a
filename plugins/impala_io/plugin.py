"""Entry point of the io plugin: registers io.Recorder and io.Replayer."""

from impala_flow.plugins import hookimpl


@hookimpl
def impala_flow_register(registry):  # type: ignore[no-untyped-def]
    pass  # filled as the recorder and the replayer land (issue 3)
