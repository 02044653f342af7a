"""Sweeps on a real distributed.LocalCluster (worker processes): the same rows with 1 and 2
workers, each the figures of a plain `impala-flow run`; a failing variant recorded while the
others go on; --resume; a worker killed with SIGKILL mid-sweep; Ctrl-C."""

from __future__ import annotations

import os
import signal
import statistics
import subprocess
import sys
import threading
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

from impala_sweep.runner import run_sweep
from impala_sweep.spec import load_sweep
from impala_sweep.task import SweepContext, run_task

from .conftest import (
    DURATION_S,
    GRAPH,
    ROOT,
    assert_row_is_the_plain_run,
    env_without_plugin_blocks,
    plain_run,
    read_rows,
    sweep_main,
    without_timing,
)

METRICS = ["eval.ate_rmse_m", "eval.drift_pct"]


def test_one_or_two_workers_same_rows_same_as_plain_runs(missions: list[Path], write_sweep: Callable[..., Path],
                                                         tmp_path: Path, capsys: Any) -> None:
    sweep = write_sweep(f"""\
graph: {GRAPH}
missions: {{simulate: {{scenario: beynes, duration_s: {DURATION_S}, seeds: [1, 2]}}}}
grid: {{slam.search_m: [1.0, 2.0]}}
metrics: [{", ".join(METRICS)}]
""")
    w1, w2 = tmp_path / "w1", tmp_path / "w2"
    assert sweep_main(str(sweep), "-o", str(w1), "--workers", "1") == 0
    assert sweep_main(str(sweep), "-o", str(w2), "--workers", "2") == 0
    out = capsys.readouterr().out
    assert f"results: {w2 / 'results.csv'}" in out and "4 tasks, 4 ok, 0 failed" in out
    rows1, rows2 = read_rows(w1), read_rows(w2)
    assert [r["task"] for r in rows2] == [t.id for t in load_sweep(sweep).tasks]  # the sweep's order
    assert without_timing(rows1) == without_timing(rows2)
    assert {r["status"] for r in rows2} == {"ok"} and {r["error"] for r in rows2} == {""}
    assert len({r["worker"] for r in rows1}) == 1 and len({r["worker"] for r in rows2}) == 2
    # the workers simulated each mission once, as `impala-flow simulate` does it, byte for byte
    for seed, mission in zip((1, 2), missions, strict=True):
        assert (w2 / "missions" / f"beynes_s{seed}_{DURATION_S}s.mcap").read_bytes() == mission.read_bytes()
    # every row is what `impala-flow run` of the same graph, mission and --set gives
    for r in rows2:
        plain = plain_run(missions[int(r["seed"]) - 1], tmp_path / f"plain-{r['task']}",
                          f"slam.search_m={r['slam.search_m']}")
        assert_row_is_the_plain_run(r, plain, METRICS)
        assert float(r["mission_s"]) == round((plain["mission_end_ns"] - plain["mission_start_ns"]) / 1e9, 6)
        assert (w2 / "tasks" / r["task"] / "metrics.json").read_text() == \
            (tmp_path / f"plain-{r['task']}" / "metrics.json").read_text()  # the task folder is the graph's ${out}
    # summary.md: mean ± std of each metric per variant, from the rows
    summary = (w2 / "summary.md").read_text(encoding="utf-8")
    for variant in ("slam.search_m=1.0", "slam.search_m=2.0"):
        xs = [float(r["eval.drift_pct"]) for r in rows2 if r["variant"] == variant]
        line = next(ln for ln in summary.splitlines() if ln.startswith(f"| {variant} |"))
        assert f"{statistics.fmean(xs):.4g} ± {statistics.stdev(xs):.2g} (n=2)" in line
    assert (w2 / "variants.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_a_failing_variant_is_recorded_and_resume_runs_only_what_is_left(
        missions: list[Path], write_sweep: Callable[..., Path], tmp_path: Path, capsys: Any) -> None:
    sweep = write_sweep(f"""\
graph: {GRAPH}
missions: {{files: ["{missions[0]}"]}}
grid: {{slam.search_m: [1.0, -1.0, 2.0]}}
metrics: [{", ".join(METRICS)}]
""")
    out = tmp_path / "out"
    assert sweep_main(str(sweep), "-o", str(out), "--workers", "2") == 1
    err = capsys.readouterr().err
    assert "1 of 3 tasks failed" in err
    rows = {r["slam.search_m"]: r for r in read_rows(out)}
    bad = rows["-1.0"]
    assert bad["status"] == "failed" and bad["eval.ate_rmse_m"] == ""
    # the variant's value reaches the graph as a --set, which the error names (engine, issue 24)
    assert bad["error"] == ("--set slam.search_m=-1.0: component 'slam' (slam.RSlam): parameter 'search_m': "
                            "-1.0 must be > 0")
    assert rows["1.0"]["status"] == rows["2.0"]["status"] == "ok"
    assert f"- `{bad['task']}`: {bad['error']}" in (out / "summary.md").read_text(encoding="utf-8")
    before = read_rows(out)

    # an interrupted sweep: the row of search_m=2.0 never written
    kept = [r for r in before if r["slam.search_m"] != "2.0"]
    with open(out / "results.csv", "w", encoding="utf-8", newline="") as f:
        import csv

        w = csv.DictWriter(f, fieldnames=list(before[0]))
        w.writeheader()
        w.writerows(kept)
    done = out / "tasks" / rows["1.0"]["task"] / "run-summary.json"
    stamp = done.stat().st_mtime_ns
    assert sweep_main(str(sweep), "--resume", str(out), "--workers", "1") == 1  # the failing variant fails again
    err = capsys.readouterr().err
    assert "1 of 3 tasks already done, 2 to run" in err
    assert done.stat().st_mtime_ns == stamp  # the ok task was not run again
    after = read_rows(out)
    assert without_timing(after) == without_timing(before)
    assert after[0] == before[0]  # its row kept as it was


def test_a_missing_metric_fails_the_task_naming_it(missions: list[Path], write_sweep: Callable[..., Path],
                                                   tmp_path: Path) -> None:
    spec = load_sweep(write_sweep(f"graph: {GRAPH}\nmissions: {{files: ['{missions[1]}']}}\n"
                                  "metrics: [eval.ate_rmse_m, eval.ate_m]\n"))
    ctx = SweepContext(str(GRAPH), str(tmp_path / "out"), tuple(spec.metrics))
    row = run_task(spec.tasks[0], ctx)
    assert row["status"] == "failed"
    assert row["error"].startswith("metric eval.ate_m: not in the run summary ('eval' reports: ")
    assert "ate_rmse_m" in row["error"]
    plain = plain_run(missions[1], tmp_path / "plain")
    assert row["eval.ate_rmse_m"] == plain["extra"]["eval"]["ate_rmse_m"]  # what it has is still reported


def test_a_worker_killed_mid_sweep_has_its_task_run_again(missions: list[Path], write_sweep: Callable[..., Path],
                                                          tmp_path: Path) -> None:
    spec = load_sweep(write_sweep(f"""\
graph: {GRAPH}
missions: {{files: ["{missions[0]}", "{missions[1]}"]}}
grid: {{slam.search_m: [1.0, 2.0]}}
metrics: [{", ".join(METRICS)}]
"""))
    killed: dict[str, Any] = {}
    out = tmp_path / "out"

    def on_client(client: Any) -> None:
        pids = client.run(os.getpid)  # worker address -> pid

        def kill_one_while_it_works() -> None:
            deadline = time.monotonic() + 120
            while time.monotonic() < deadline and not killed:
                for addr, keys in client.processing().items():
                    # a task of this worker that has started: its graph writes its log
                    started = [k for k in keys if str(k).startswith("task-")
                               and (out / "tasks" / str(k)[5:] / "run.log").exists()]
                    if started:
                        time.sleep(0.5)  # well into the graph's run
                        os.kill(pids[addr], signal.SIGKILL)
                        killed.update(pid=pids[addr], key=started[0])
                        return
                time.sleep(0.02)

        threading.Thread(target=kill_one_while_it_works, daemon=True).start()

    outcome = run_sweep(spec, out, workers=2, progress=False, on_client=on_client)
    assert killed, "no worker was killed"
    rows = read_rows(out)
    assert (outcome.ok, outcome.failed, outcome.interrupted) == (4, 0, False)
    assert [r["task"] for r in rows] == [t.id for t in spec.tasks] and {r["status"] for r in rows} == {"ok"}
    assert not any(r["worker"].endswith(f":{killed['pid']}") for r in rows)  # all finished elsewhere
    # the task that was running on the killed worker gives what it gives alone
    victim = next(t for t in spec.tasks if f"task-{t.id}" == killed["key"])
    alone = run_task(victim, SweepContext(str(GRAPH), str(tmp_path / "alone"), tuple(spec.metrics)))
    assert without_timing([next(r for r in rows if r["task"] == victim.id)]) == without_timing(
        [{k: "" if alone.get(k) is None else str(alone[k]) for k in rows[0]}])


def test_ctrl_c_keeps_what_is_done(missions: list[Path], write_sweep: Callable[..., Path], tmp_path: Path) -> None:
    sweep = write_sweep(f"""\
graph: {GRAPH}
missions: {{files: ["{missions[0]}", "{missions[1]}"]}}
grid: {{slam.search_m: [1.0, 2.0, 3.0]}}
metrics: [{", ".join(METRICS)}]
""")
    out = tmp_path / "out"
    proc = subprocess.Popen([sys.executable, "-m", "impala_flow", "sweep", str(sweep), "-o", str(out),
                             "--workers", "1"], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, cwd=ROOT,
                            env=env_without_plugin_blocks())
    try:
        deadline = time.monotonic() + 120
        while time.monotonic() < deadline:
            if (out / "results.csv").exists() and len(read_rows(out)) >= 1:
                break
            assert proc.poll() is None, proc.communicate()
            time.sleep(0.1)
        proc.send_signal(signal.SIGINT)
        stdout, stderr = proc.communicate(timeout=60)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
    assert proc.returncode == 130, stderr
    assert "interrupted" in stderr and f"--resume {out}" in stderr
    assert "Traceback" not in stderr + stdout and "Error" not in stderr, stderr
    assert stderr.splitlines()[-1] == (f"impala-flow sweep: interrupted; {len(read_rows(out))} of 6 tasks done, "
                                       f"resume with --resume {out}")
    rows = read_rows(out)
    assert 1 <= len(rows) < 6 and {r["status"] for r in rows} == {"ok"}
    assert "Interrupted:" in (out / "summary.md").read_text(encoding="utf-8")
    assert sweep_main(str(sweep), "--resume", str(out), "--workers", "2") == 0
    done = read_rows(out)
    assert [r["task"] for r in done] == [t.id for t in load_sweep(sweep).tasks]
    assert [r for r in done if r["task"] in {x["task"] for x in rows}] == rows  # kept as they were


def test_tasks_undo_dasks_malloc_trim_threshold_only_when_dask_set_it() -> None:
    code = "from impala_sweep.task import undo_dask_malloc_trim as u; print(u(), u())"
    for value, done in (("65536", "True False"), ("1000000", "False False"), (None, "False False")):
        env = env_without_plugin_blocks()
        env.pop("MALLOC_TRIM_THRESHOLD_", None)
        if value is not None:
            env["MALLOC_TRIM_THRESHOLD_"] = value
        out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env, check=True)
        assert out.stdout.split() == done.split(), value
