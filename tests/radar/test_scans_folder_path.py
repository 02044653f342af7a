"""A dataset source's ``folder`` is a path a graph reads: relative to the graph file's folder
(wherever the user runs it from), and nothing the graph writes may go inside it."""

from __future__ import annotations

from mcap.reader import make_reader

from impala_flow.cli import main

from ._dataset_files import navtech_folder

GRAPH = """\
name: scans
clock: {{mode: replay, speed: max}}
components:
  scans: {{type: radar.OxfordScans, params: {{folder: ../data}}}}
record: {{path: {out}, streams: [scans.beams]}}
"""


def test_folder_is_resolved_against_the_graph_file(tmp_path, monkeypatch, capsys):
    navtech_folder(tmp_path / "data", n_scans=2)
    (tmp_path / "graphs").mkdir()
    graph = tmp_path / "graphs" / "scans.yaml"
    graph.write_text(GRAPH.format(out="../out/scans.mcap"))
    elsewhere = tmp_path / "a" / "b"
    elsewhere.mkdir(parents=True)
    monkeypatch.chdir(elsewhere)  # ../data from here does not exist: only the graph's folder finds it
    assert main(["run", str(graph), "--no-progress"]) == 0, capsys.readouterr().err
    with open(tmp_path / "out" / "scans.mcap", "rb") as f:
        beams = sum(1 for _ in make_reader(f).iter_messages(topics=["scans/beams"]))
    assert beams == 2 * 400  # two turns of 400 rows, every row valid


def test_a_recording_inside_the_dataset_folder_is_refused(tmp_path, capsys):
    navtech_folder(tmp_path / "data", n_scans=2)
    (tmp_path / "graphs").mkdir()
    graph = tmp_path / "graphs" / "scans.yaml"
    graph.write_text(GRAPH.format(out="../data/radar/out.mcap"))
    assert main(["run", str(graph), "--no-progress"]) == 2
    err = capsys.readouterr().err
    assert "is inside the input of component 'scans' (radar.OxfordScans) parameter 'folder'" in err
    assert not (tmp_path / "data" / "radar" / "out.mcap").exists()
