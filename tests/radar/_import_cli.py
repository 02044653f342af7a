"""`impala-flow import` as the tests call it: a refused import (one line, no output, no partial
file), the printed import block, and a RADIATE import read back."""

from __future__ import annotations

from impala_flow.cli import main
from impala_flow.io import MissionReader


def refused(fmt, folder, capsys, *extra, code=1) -> str:
    """The one error line of an import of ``folder`` that must exit ``code`` writing nothing."""
    out = folder.parent / f"{folder.name}-out.mcap"
    got = main(["import", fmt, str(folder), "-o", str(out), "--no-progress", *extra])
    err = capsys.readouterr().err.strip().splitlines()
    assert got == code and len(err) == 1, (got, err)
    assert not out.exists() and not list(folder.parent.glob(f".{out.name}*"))  # nothing written half-way
    return err[0]


def import_block(text: str) -> dict[str, str]:
    """The import block printed by the command as {key: value} (lines 'key: value')."""
    return {k.strip(): v.strip() for k, _, v in (ln.partition(":") for ln in text.splitlines()) if v}


def import_radiate(folder, out, *extra):
    """``(beams, truth, metadata)`` of a RADIATE import of ``folder`` (beams and truth as
    ``(t_ns, data)``). The synthetic GPS files are written on the radar's clock: no GPS offset
    (the real one's has its own test). An output asked inside the dataset folder, which the
    command refuses, goes beside it."""
    if out.parent == folder:
        out = folder.parent / f"{folder.name}-{out.name}"
    assert main(["import", "radiate", str(folder), "-o", str(out), "--no-progress", "--gps-offset-s", "0", *extra]) == 0
    with MissionReader(out) as r:
        beams = [(m.t_ns, m.data) for m in r.messages(["radar/beams"])]
        truth = [(m.t_ns, m.data) for m in r.messages(["truth/pose"])] if "truth/pose" in r.topics else []
        meta = r.metadata().get("impala_flow.source.radiate", {})
    return beams, truth, meta
