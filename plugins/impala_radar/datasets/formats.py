"""The dataset formats the ``import`` command and the dataset sources read, and the reader of each."""

from __future__ import annotations

from .common import NavtechDataset

__all__ = ["FORMATS", "open_dataset"]

#: dataset formats the ``import`` command and the sources read
FORMATS = ("oxford", "boreas", "radiate")


def open_dataset(fmt: str, folder: str, **options: object) -> NavtechDataset:
    """The reader of format ``fmt`` (one of :data:`FORMATS`) on ``folder``."""
    if fmt == "oxford":
        from .oxford import OxfordDataset as cls
    elif fmt == "boreas":
        from .boreas import BoreasDataset as cls
    elif fmt == "radiate":
        from .radiate import RadiateDataset as cls
    else:
        raise ValueError(f"unknown dataset format {fmt!r} (known: {', '.join(FORMATS)})")
    return cls(folder, **options)  # type: ignore[arg-type]
