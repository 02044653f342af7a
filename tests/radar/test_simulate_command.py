"""`impala-flow simulate`: a mission file the replayer plays back, byte-identical per seed."""

from __future__ import annotations

import hashlib

import pytest
from mcap.reader import make_reader

from impala_flow.cli import main
from impala_flow.io import MissionReader


def _sha(path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


def test_same_seed_same_bytes_other_seed_other_world(tmp_path, capsys):
    a, b, c = tmp_path / "a.mcap", tmp_path / "b.mcap", tmp_path / "c.mcap"
    for path, seed in ((a, 3), (b, 3), (c, 4)):
        assert main(["simulate", "beynes", "-o", str(path), "--duration", "2s", "--seed", str(seed),
                     "--no-progress"]) == 0
    assert _sha(a) == _sha(b)
    assert _sha(a) != _sha(c)
    with open(a, "rb") as f:  # read by the mcap library itself
        counts: dict[str, int] = {}
        for _, ch, _ in make_reader(f).iter_messages():
            counts[ch.topic] = counts.get(ch.topic, 0) + 1
    # 2 s: 1 turn/s x 360 beams (RADAR.md), odometer 50 Hz, gyro 100 Hz, RTK-GPS 10 Hz
    assert counts["radar/beams"] == 720
    assert counts["odometer/speed"] == 100 and counts["gyro/yaw_rate"] == 200 and counts["gps/pose"] == 20
    with MissionReader(a) as r:
        meta = r.metadata()
        first = next(iter(r.messages(["radar/beams"])))
        # stamped from the default epoch, 2026-01-01T00:00:00Z = 1 767 225 600 s after 1970; the
        # first beam at the middle of its 1/360 s
        assert first.t_ns == 1_767_225_600 * 10**9 + round(1e9 / 720)
        beams = [m.data for m in r.messages(["radar/beams"], end_ns=first.t_ns + 10_000_000)]
    assert "radar.Simulator" in meta["impala_flow.graph"]["yaml"]  # the file says how it was made
    assert beams and beams[0].config.name.lower().startswith("impala") and beams[0].up.dtype.name == "float32"


def test_unknown_scenario_is_a_one_line_usage_error(tmp_path, capsys):
    assert main(["simulate", "nowhere", "-o", str(tmp_path / "x.mcap")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("impala-flow simulate: error: scenario 'nowhere':")


def test_a_bad_scenario_file_exits_2_naming_file_key_and_line(tmp_path, capsys):
    bad = tmp_path / "k2pi-typo.yaml"
    bad.write_text("world: campus\nroute: open\nseed: 1\npreset: k2pi\nradar:\n  tx_power_dbm: 20.0\n"
                   "  antenna_gain_db: -20.0\n")
    out = tmp_path / "x.mcap"
    assert main(["simulate", str(bad), "-o", str(out), "--duration", "1"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and f"{bad}:7:20: radar.antenna_gain_db = -20.0" in err[0]
    assert not out.exists() and not list(tmp_path.glob("*.mcap*"))  # nothing simulated, nothing written


def test_the_epoch_moves_the_stamps_not_the_mission(tmp_path):
    """The same seed from t = 0 and from another date: the same samples, shifted by the epoch."""
    from impala_radar.simulator.component import Simulator, epoch_ns

    assert epoch_ns("1970-01-02T00:00:00Z") == 86_400 * 10**9 and epoch_ns("") == 0
    assert epoch_ns("2026-01-01T01:00:00+01:00") == 1_767_225_600 * 10**9  # a zone is honoured

    def stream(epoch: str) -> list:
        sim = Simulator("sim", scenario="beynes", duration_s=0.2, seed=5, epoch_utc=epoch)
        sim.start()
        return list(sim.generate())

    zero, dated = stream(""), stream("2030-06-01T12:00:00Z")
    shift = epoch_ns("2030-06-01T12:00:00Z")
    assert zero[0][0] == 0 and [t + shift for t, _, _ in zero] == [t for t, _, _ in dated]
    assert all((a[1], getattr(a[2], "azimuth_rad", None)) == (b[1], getattr(b[2], "azimuth_rad", None))
               for a, b in zip(zero, dated, strict=True))


def test_a_bad_epoch_is_a_one_line_error(tmp_path, capsys):
    from impala_radar.simulator.component import Simulator

    with pytest.raises(ValueError, match="epoch_utc 'yesterday' is not an ISO 8601"):
        Simulator("sim", epoch_utc="yesterday").start()


def test_simulate_epoch_option(tmp_path, capsys):
    out = tmp_path / "zero.mcap"
    assert main(["simulate", "beynes", "-o", str(out), "--duration", "1s", "--epoch-utc", "", "--no-progress"]) == 0
    with MissionReader(out) as r:
        assert next(iter(r.messages(["radar/beams"]))).t_ns == round(1e9 / 720)  # t = 0 + half a beam
    bad = tmp_path / "bad.mcap"
    assert main(["simulate", "beynes", "-o", str(bad), "--epoch-utc", "soon", "--no-progress"]) == 2
    assert "epoch_utc 'soon' is not an ISO 8601" in capsys.readouterr().err and not bad.exists()
