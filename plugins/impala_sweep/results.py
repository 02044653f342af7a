"""A sweep's outputs: ``results.csv`` (one row per task), ``summary.md`` (mean ± std of each
metric per variant) and ``variants.png`` (a box plot of each metric, one box per variant).

Rows are appended to ``results.csv`` as tasks finish (flushed, so an interrupted sweep
keeps them); :meth:`Results.finalize` then rewrites the file in the sweep's task order, the
last row of each task only, so the same sweep gives the same file whatever finished first.
"""

from __future__ import annotations

import csv
import math
import os
import statistics
from pathlib import Path
from typing import Any

from .spec import SweepError, SweepSpec, format_value

__all__ = ["Results", "columns", "RESULTS", "SUMMARY", "FIGURE", "STATUS_OK", "STATUS_FAILED"]

RESULTS, SUMMARY, FIGURE = "results.csv", "summary.md", "variants.png"
STATUS_OK, STATUS_FAILED = "ok", "failed"
_HEAD = ["task", "mission", "seed", "duration_s", "repeat", "variant"]
_TAIL = ["samples", "lost", "mission_s", "wall_s", "worker", "status", "error"]


def columns(spec: SweepSpec) -> list[str]:
    """The columns of ``results.csv``: the task, every grid parameter, every metric, the counters."""
    return _HEAD + spec.param_names + spec.metrics + _TAIL


def _cell(key: str, value: Any, params: set[str]) -> str:
    if value is None:
        return ""
    if key in params:
        return format_value(value)
    if key == "wall_s" and isinstance(value, float):
        return f"{value:.3f}"
    return str(value)


class Results:
    """The rows of one sweep folder (those already there when resuming, then the new ones)."""

    def __init__(self, spec: SweepSpec, out_dir: str | Path, resume: bool = False) -> None:
        self.spec = spec
        self.dir = Path(out_dir)
        self.path = self.dir / RESULTS
        self.columns = columns(spec)
        self._params = set(spec.param_names)
        self.rows: dict[str, dict[str, str]] = {}  # task id -> its last row (as written)
        if self.path.exists():
            if not resume:
                raise SweepError(f"{self.path}: a sweep already wrote results here: --resume {self.dir} to "
                                 "finish it, or -o another folder")
            self._read()
        self.dir.mkdir(parents=True, exist_ok=True)
        new = not self.path.exists()
        self._file = open(self.path, "a", encoding="utf-8", newline="")
        self._writer = csv.DictWriter(self._file, fieldnames=self.columns, extrasaction="ignore")
        if new:
            self._writer.writeheader()
            self._file.flush()

    def _read(self) -> None:
        with open(self.path, encoding="utf-8", newline="") as f:
            reader = csv.DictReader(f)
            if reader.fieldnames != self.columns:
                raise SweepError(f"{self.path}: its columns are not this sweep's (another sweep file, or one "
                                 f"edited since?): expected {','.join(self.columns)}")
            for row in reader:
                self.rows[row["task"]] = dict(row)

    def done(self) -> set[str]:
        """Tasks with an ``ok`` row: a resumed sweep skips them (failed ones run again)."""
        return {k for k, r in self.rows.items() if r.get("status") == STATUS_OK}

    def add(self, row: dict[str, Any]) -> dict[str, str]:
        cells = {k: _cell(k, row.get(k), self._params) for k in self.columns}
        self._writer.writerow(cells)
        self._file.flush()
        self.rows[cells["task"]] = cells
        return cells

    def finalize(self) -> None:
        """Rewrite ``results.csv``: the sweep's task order, then any other task (a resumed
        folder's rows of tasks the sweep file no longer has), one row per task."""
        self._file.close()
        order = {t.id: i for i, t in enumerate(self.spec.tasks)}
        rows = sorted(self.rows.values(), key=lambda r: (order.get(r["task"], len(order)), r["task"]))
        tmp = self.path.with_name(f".{RESULTS}.{os.getpid()}.part")
        with open(tmp, "w", encoding="utf-8", newline="") as f:
            w = csv.DictWriter(f, fieldnames=self.columns)
            w.writeheader()
            w.writerows(rows)
        os.replace(tmp, self.path)

    def counts(self) -> tuple[int, int]:
        """(ok, failed) tasks of this sweep."""
        ids = {t.id for t in self.spec.tasks}
        st = [r.get("status") for k, r in self.rows.items() if k in ids]
        return st.count(STATUS_OK), st.count(STATUS_FAILED)

    # -- summary.md and the figure -------------------------------------------------------

    def _values(self) -> dict[str, dict[str, list[float]]]:
        """variant -> metric -> values of the ok rows, in the sweep's variant order."""
        out: dict[str, dict[str, list[float]]] = {v: {m: [] for m in self.spec.metrics} for v in self.spec.variants}
        for r in self.rows.values():
            if r.get("status") != STATUS_OK:
                continue
            per = out.setdefault(r["variant"], {m: [] for m in self.spec.metrics})
            for m in self.spec.metrics:
                try:
                    x = float(r.get(m) or "nan")
                except ValueError:
                    continue
                if math.isfinite(x):
                    per[m].append(x)
        return out

    def write_summary(self, note: str = "") -> Path:
        values = self._values()
        ids = {t.id for t in self.spec.tasks}
        by_variant: dict[str, list[dict[str, str]]] = {}
        for k, r in self.rows.items():
            if k in ids:
                by_variant.setdefault(r["variant"], []).append(r)
        ok, failed = self.counts()
        lines = [f"# Sweep {self.spec.path.name}", "",
                 f"Graph `{self.spec.graph}`; {len(self.spec.tasks)} tasks: {ok} ok, {failed} failed, "
                 f"{len(self.spec.tasks) - ok - failed} not run." + (f" {note}" if note else ""), "",
                 "Mean ± standard deviation over the ok tasks of each variant (missions, seeds, repeats); "
                 "n = number of values.", "",
                 "| variant | ok | failed | " + " | ".join(self.spec.metrics) + " | wall_s |",
                 "|---|---:|---:|" + "---:|" * (len(self.spec.metrics) + 1)]
        for variant, per in values.items():
            rows = by_variant.get(variant, [])
            n_ok = sum(r.get("status") == STATUS_OK for r in rows)
            n_failed = sum(r.get("status") == STATUS_FAILED for r in rows)
            walls = [float(r["wall_s"]) for r in rows if r.get("status") == STATUS_OK and r.get("wall_s")]
            cells = [_mean_std(per[m]) for m in self.spec.metrics] + [_mean_std(walls)]
            lines.append(f"| {variant} | {n_ok} | {n_failed} | " + " | ".join(cells) + " |")
        bad = [r for k, r in self.rows.items() if k in ids and r.get("status") == STATUS_FAILED]
        if bad:
            lines += ["", "## Failed tasks", ""]
            order = {t.id: i for i, t in enumerate(self.spec.tasks)}
            lines += [f"- `{r['task']}`: {r.get('error') or '?'}" for r in sorted(bad, key=lambda r: order[r["task"]])]
        path = self.dir / SUMMARY
        path.write_text("\n".join(lines) + "\n", encoding="utf-8")
        return path

    def write_figure(self) -> Path | None:
        """One box plot per metric, one box per variant (the ok tasks); None without any value."""
        values = self._values()
        if not any(v for per in values.values() for v in per.values()):
            return None
        from matplotlib.backends.backend_agg import FigureCanvasAgg
        from matplotlib.figure import Figure

        metrics = self.spec.metrics
        variants = list(values)
        longest = max(len(part) for v in variants for part in v.split(", "))
        width = max(4.0, min(0.09 * longest, 3.0) * len(variants) + 1.5)
        fig = Figure(figsize=(width, 3.2 * len(metrics)), layout="constrained")
        FigureCanvasAgg(fig)
        axes = fig.subplots(len(metrics), 1, squeeze=False)[:, 0]
        for ax, m in zip(axes, metrics, strict=True):
            data = [values[v][m] for v in variants]
            ax.boxplot([d if d else [math.nan] for d in data], showmeans=True)
            ax.set_xticks(range(1, len(variants) + 1), [v.replace(", ", "\n") for v in variants], fontsize=7)
            ax.set_ylabel(m)
            ax.grid(axis="y", alpha=0.3)
            for i, d in enumerate(data, start=1):
                if d:
                    ax.plot([i] * len(d), d, ".", color="0.3", ms=3)
                else:
                    ax.text(i, 0.5, "no ok task", transform=ax.get_xaxis_transform(), ha="center", color="0.4",
                            fontsize=8)
        axes[0].set_title(f"{self.spec.path.name}: {self.spec.graph.name}, one box per variant")
        path = self.dir / FIGURE
        fig.savefig(path, dpi=110)
        return path


def _mean_std(xs: list[float]) -> str:
    if not xs:
        return "–"
    mean = statistics.fmean(xs)
    if len(xs) == 1:
        return f"{mean:.4g} (n=1)"
    return f"{mean:.4g} ± {statistics.stdev(xs):.2g} (n={len(xs)})"
