"""What `impala-flow import` and `impala-flow simulate` may write: only their own -o file. An output equal
to, inside or over an input (links resolved), an existing folder, pipe or device, or an existing file
without --overwrite is refused before any work, in one line, exit 2; the mission is written to a hidden
'.part' file renamed on success only, so a failed or interrupted run leaves nothing, not even the folders
it made. Synthetic datasets made here."""

from __future__ import annotations

import hashlib
import os
import signal
from pathlib import Path

import pytest

from impala_flow.cli import main
from impala_flow.io import MissionReader

from ._dataset_files import navtech_folder

OXFORD_GT_HEADER = ("source_radar_timestamp,destination_radar_timestamp,x,y,z,roll,pitch,yaw,"
                    "source_timestamp,destination_timestamp")


def _sha(path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


def _tree(root) -> dict[str, str]:
    """Every file under ``root`` (relative path -> content hash; folders and other kinds by name)."""
    out = {}
    for dirpath, dirnames, filenames in os.walk(root):
        for name in dirnames:
            out[os.path.relpath(os.path.join(dirpath, name), root)] = "folder"
        for name in filenames:
            p = os.path.join(dirpath, name)
            out[os.path.relpath(p, root)] = _sha(Path(p)) if os.path.isfile(p) else "other"
    return out


@pytest.fixture
def dataset(tmp_path):
    """An Oxford folder: 3 scans and a ground-truth file (2 relative poses)."""
    folder = tmp_path / "ox"
    paths = navtech_folder(folder, n_scans=3)
    t = [int(p.stem) for p in paths]
    (folder / "gt").mkdir()
    (folder / "gt" / "radar_odometry.csv").write_text(
        OXFORD_GT_HEADER + "\n" + "".join(f"{t[k + 1]},{t[k]},1.0,0.0,0,0,0,0.0,{t[k + 1]},{t[k]}\n" for k in range(2)))
    return folder


def _refused(capsys, *argv) -> str:
    code = main([*argv, "--no-progress"])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and len(err) == 1, (code, err)
    return err[0]


@pytest.mark.parametrize("target", ["gt/radar_odometry.csv", "radar/SCAN", "new.mcap"])
def test_an_output_inside_the_dataset_is_refused_and_nothing_changes(dataset, capsys, target):
    target = target.replace("SCAN", sorted(p.name for p in (dataset / "radar").iterdir())[0])
    before = _tree(dataset)
    line = _refused(capsys, "import", "oxford", str(dataset), "-o", str(dataset / target))
    assert line == (f"impala-flow import: error: -o '{dataset / target}' is inside the dataset folder '{dataset}': "
                    "write outside it")
    assert _tree(dataset) == before


def test_the_dataset_folder_itself_and_a_folder_holding_it_are_refused(dataset, capsys):
    before = _tree(dataset.parent)
    line = _refused(capsys, "import", "oxford", str(dataset), "-o", str(dataset))
    assert f"-o '{dataset}' is the dataset folder '{dataset}' itself" in line
    line = _refused(capsys, "import", "oxford", str(dataset), "-o", str(dataset.parent))
    assert f"-o '{dataset.parent}' contains the dataset folder '{dataset}'" in line
    assert _tree(dataset.parent) == before


def test_a_link_to_an_input_is_resolved(dataset, tmp_path, capsys):
    gt = dataset / "gt" / "radar_odometry.csv"
    link = tmp_path / "looks-new.mcap"
    link.symlink_to(gt)
    before = _sha(gt)
    line = _refused(capsys, "import", "oxford", str(dataset), "-o", str(link), "--overwrite")
    assert f"-o '{link}' is inside the dataset folder '{dataset}'" in line
    assert _sha(gt) == before and link.is_symlink()


def test_an_existing_folder_is_refused_before_any_work(dataset, tmp_path, capsys):
    out = tmp_path / "missions"
    out.mkdir()
    line = _refused(capsys, "import", "oxford", str(dataset), "-o", str(out), "--overwrite")
    assert line.endswith(f"-o '{out}' is a folder: give a file name, e.g. '{out / 'mission.mcap'}'")
    assert not any(out.iterdir()) and not list(tmp_path.glob(".*part"))


@pytest.mark.skipif(not hasattr(os, "mkfifo"), reason="no named pipes here")
def test_a_pipe_is_never_replaced(dataset, tmp_path, capsys):
    fifo = tmp_path / "pipe.mcap"
    os.mkfifo(fifo)
    line = _refused(capsys, "import", "oxford", str(dataset), "-o", str(fifo), "--overwrite")
    assert line.endswith(f"-o '{fifo}' exists and is not a regular file (device, pipe or socket): never replaced; "
                         "write elsewhere")
    assert fifo.is_fifo()


def test_an_existing_file_needs_overwrite_and_is_replaced_only_by_a_complete_import(dataset, tmp_path, capsys):
    out = tmp_path / "mine.mcap"
    out.write_text("the user's file\n")
    line = _refused(capsys, "import", "oxford", str(dataset), "-o", str(out))
    assert line.endswith(f"-o '{out}' exists: --overwrite replaces it (once the new file is complete)")
    assert out.read_text() == "the user's file\n"
    # --overwrite on a failing import (the last scan truncated): the old file stays as it was
    scans = sorted((dataset / "radar").iterdir())
    good = scans[-1].read_bytes()
    scans[-1].write_bytes(good[:200])
    assert main(["import", "oxford", str(dataset), "-o", str(out), "--overwrite", "--no-progress"]) == 1
    assert f"{scans[-1]}: truncated PNG" in capsys.readouterr().err
    assert out.read_text() == "the user's file\n" and not list(tmp_path.glob(".*part"))
    scans[-1].write_bytes(good)
    assert main(["import", "oxford", str(dataset), "-o", str(out), "--overwrite", "--no-progress"]) == 0
    with MissionReader(out) as r:
        assert sum(1 for _ in r.messages(["radar/beams"])) == 3 * 400
        assert sum(1 for _ in r.messages(["truth/pose"])) == 3  # the first scan's identity and 2 relative poses
    assert not list(tmp_path.glob(".*part"))


def test_a_failed_import_leaves_neither_its_file_nor_the_folders_it_made(dataset, tmp_path, capsys):
    scans = sorted((dataset / "radar").iterdir())
    scans[1].write_bytes(scans[1].read_bytes()[:200])  # fails after the first scan was recorded
    out = tmp_path / "new" / "deeper" / "m.mcap"
    assert main(["import", "oxford", str(dataset), "-o", str(out), "--no-progress"]) == 1
    assert f"{scans[1]}: truncated PNG" in capsys.readouterr().err
    assert not (tmp_path / "new").exists()


def test_an_interrupted_import_leaves_nothing(dataset, tmp_path, monkeypatch):
    """Ctrl-C (SIGINT) while the scans are read: the run stops cleanly (exit 130) and the partial file goes."""
    from impala_radar.datasets.oxford import OxfordDataset

    read = OxfordDataset.read_scan

    def read_then_ctrl_c(self, k):
        if k == 1:
            os.kill(os.getpid(), signal.SIGINT)
        return read(self, k)

    monkeypatch.setattr(OxfordDataset, "read_scan", read_then_ctrl_c)
    out = tmp_path / "m.mcap"
    assert main(["import", "oxford", str(dataset), "-o", str(out), "--no-progress"]) == 130
    assert not out.exists() and not list(tmp_path.glob(".*part"))


def test_a_file_created_meanwhile_is_not_overwritten(dataset, tmp_path, capsys, monkeypatch):
    from impala_radar.datasets.oxford import OxfordDataset

    read = OxfordDataset.read_scan
    out = tmp_path / "m.mcap"

    def read_while_someone_writes(self, k):
        if k == 1:
            out.write_text("someone else's\n")
        return read(self, k)

    monkeypatch.setattr(OxfordDataset, "read_scan", read_while_someone_writes)
    assert main(["import", "oxford", str(dataset), "-o", str(out), "--no-progress"]) == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert err == [f"impala-flow import: error: -o '{out}' was created by something else during the run: "
                   "not overwritten (--overwrite replaces it)"]
    assert out.read_text() == "someone else's\n" and not list(tmp_path.glob(".*part"))


SCENARIO = "world: beynes\nroute: default\nseed: 1\npreset: impala\n"


def test_simulate_refuses_its_scenario_file_and_an_existing_output(tmp_path, capsys):
    scenario = tmp_path / "my.yaml"
    scenario.write_text(SCENARIO)
    line = _refused(capsys, "simulate", str(scenario), "-o", str(scenario), "--duration", "1s")
    assert line == (f"impala-flow simulate: error: -o '{scenario}' is the scenario file '{scenario}' itself: "
                    "it would be overwritten")
    assert scenario.read_text() == SCENARIO
    out = tmp_path / "m.mcap"
    assert main(["simulate", str(scenario), "-o", str(out), "--duration", "1s", "--no-progress"]) == 0
    assert capsys.readouterr().out.strip().splitlines()[-1].startswith(f"simulated:    {out} ")
    first = _sha(out)
    line = _refused(capsys, "simulate", str(scenario), "-o", str(out), "--duration", "2s")
    assert line.endswith(f"-o '{out}' exists: --overwrite replaces it (once the new file is complete)")
    assert _sha(out) == first
    # replaced by the same run: the same bytes (the temporary name leaves no trace in the file)
    assert main(["simulate", str(scenario), "-o", str(out), "--duration", "1s", "--no-progress", "--overwrite"]) == 0
    assert _sha(out) == first and not list(tmp_path.glob(".*part"))


def test_a_file_name_too_long_is_refused_before_any_work(dataset, tmp_path, capsys):
    out = tmp_path / ("m" * 251 + ".mcap")  # 256 bytes: one more than Linux file systems allow
    line = _refused(capsys, "import", "oxford", str(dataset), "-o", str(out))
    assert line.endswith("-o: a file name of 256 bytes, longer than the file system allows (255)")
