"""``export --csv`` is never silently lossy: arrays become rows (one per object or pose, with
its index), columns (small arrays), .npy files (--npy) or a one-line refusal naming the field."""

from __future__ import annotations

import csv
from pathlib import Path

import numpy as np
import pytest

import impala_msgs
from impala_flow import msgs
from impala_flow.cli import main
from impala_flow.io import MissionWriter, run_codecs

RNG = np.random.default_rng(3)
STATES = [impala_msgs.ObjectStates(ids=np.arange(n, dtype=np.int64) + 10 * k, xy_m=RNG.normal(size=(n, 2)),
                            v_xy_mps=RNG.normal(size=(n, 2)))
          for k, n in enumerate([3, 0, 2])]
TRAJ = msgs.Trajectory2D(t_ns=np.array([5, 6, 7, 8], np.int64), xyt=RNG.normal(size=(4, 3)))
BIG_GRID = msgs.Grid(RNG.random((40, 30)).astype(np.float32), 0.2, 1.0, 2.0)


@pytest.fixture
def mission(tmp_path: Path) -> Path:
    path = tmp_path / "m.mcap"
    with MissionWriter(path, codecs=run_codecs(), foxglove=False) as w:
        w.add_topic("movers/states", impala_msgs.ObjectStates)
        w.add_topic("slam/trajectory", msgs.Trajectory2D)
        w.add_topic("slam/map", msgs.Grid)
        for k, s in enumerate(STATES):
            w.write("movers/states", 1000 * k, s)
        w.write("slam/trajectory", 9, TRAJ)
        w.write("slam/map", 10, BIG_GRID)
        w.write("slam/map", 20, BIG_GRID)
    return path


def _csv(path: Path) -> list[dict[str, str]]:
    return list(csv.DictReader(path.read_text().splitlines()))


def test_object_states_one_row_per_object(mission: Path, tmp_path: Path) -> None:
    out = tmp_path / "s.csv"
    assert main(["export", str(mission), "--topic", "movers/states", "--csv", "-o", str(out)]) == 0
    rows = _csv(out)
    assert len(rows) == 3 + 1 + 2  # an empty message still gives its row: its time is not lost
    expected = []
    for k, s in enumerate(STATES):
        if not len(s.ids):
            expected.append((str(1000 * k), "", "", "", ""))
        for i in range(len(s.ids)):
            expected.append((str(1000 * k), str(i), str(int(s.ids[i])), repr(float(s.xy_m[i, 0])),
                             repr(float(s.v_xy_mps[i, 1]))))
    assert [(r["t_ns"], r["index"], r["ids"], r["xy_m.0"], r["v_xy_mps.1"]) for r in rows] == expected
    assert all(r["frame"] == "map" for r in rows)


def test_trajectory_one_row_per_pose(mission: Path, tmp_path: Path) -> None:
    out = tmp_path / "t.csv"
    assert main(["export", str(mission), "--topic", "slam/trajectory", "--csv", "-o", str(out)]) == 0
    rows = _csv(out)
    header = out.read_text().splitlines()[0].split(",")
    assert header == ["t_ns", "index", "msg.t_ns", "xyt.0", "xyt.1", "xyt.2", "frame"]
    assert [r["t_ns"] for r in rows] == ["9"] * 4 and [int(r["msg.t_ns"]) for r in rows] == [5, 6, 7, 8]
    got = np.array([[float(r[f"xyt.{j}"]) for j in range(3)] for r in rows])
    assert np.array_equal(got, TRAJ.xyt) and [r["index"] for r in rows] == ["0", "1", "2", "3"]


def test_grid_refused_with_the_field_named_or_written_as_npy(mission: Path, tmp_path: Path,
                                                             capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "g.csv"
    assert main(["export", str(mission), "--topic", "slam/map", "--csv", "-o", str(out)]) == 1
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and "'data' is a 40x30 array" in err and "--npy" in err
    assert not out.exists()
    npy = tmp_path / "npy"
    assert main(["export", str(mission), "--topic", "slam/map", "--csv", "-o", str(out), "--npy", str(npy)]) == 0
    rows = _csv(out)
    assert [r["t_ns"] for r in rows] == ["10", "20"] and rows[0]["cell_m"] == "0.2"
    for r in rows:
        assert np.array_equal(np.load(npy / r["data"], allow_pickle=False), BIG_GRID.data)
