"""The ROS 2 tests need mcap-ros2-support (the ros2 extra) and the ros2 plugin installed: each module skips
without the library (``pytest.importorskip`` first), each test without the plugin (``ros2_codecs``)."""

from __future__ import annotations

import pytest


@pytest.fixture(scope="session")
def ros2_codecs():
    from impala_flow.io import run_codecs
    from impala_flow.plugins import load_registry

    reg = load_registry()
    if "ros2" not in reg.plugins:
        pytest.skip(f"the ros2 plugin is not installed in this environment ({reg.broken.get('ros2')})")
    return run_codecs(reg)
