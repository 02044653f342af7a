"""The Foxglove view: view.FoxgloveBridge (live, over WebSocket), the ``impala-flow view`` command and
the Foxglove mirrors recordings carry (:mod:`impala_view.mirrors`)."""
