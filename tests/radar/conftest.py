import pytest


@pytest.fixture
def folder(tmp_path):
    """An empty dataset folder; outputs go beside it (an output inside it is refused)."""
    d = tmp_path / "data"
    d.mkdir()
    return d
