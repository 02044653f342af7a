"""Mission report: ``metrics.json`` and the figures of seed 1 §4.1.2 (Fig. 10b, Fig. 12).

``write_report(folder, ...)`` writes::

    metrics.json        every figure, units in the key names; the baseline's prefixed baseline_;
                        ``gaps``: per stream, the time ranges with no sample ([start_s, end_s])
    error_vs_distance.png   position error along the path (Fig. 12), baseline beside
    trajectory_map.png  estimated and true trajectories over the radar map (Fig. 10b)
    map.png             the radar map alone
    pair_errors.png     with pairs: every consecutive pair's relative-motion error
    twist_errors.png    with an estimated twist: speed and yaw-rate errors against time, the true
                        speed and yaw rate above them

``format_metrics`` / ``load_metrics`` let a command print a report's figures.
"""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

import numpy as np

from impala_flow.msgs import Grid

from .metrics import TrajectoryMetrics, TwistErrors, gap_spans_ns

__all__ = ["write_report", "format_metrics", "load_metrics", "METRICS_FILE", "find_gaps", "gap_summary", "new_figure",
           "save_figure", "show_map"]

METRICS_FILE = "metrics.json"
_EST, _TRUTH, _BASE = "#d62728", "#2ca02c", "#1f77b4"


def find_gaps(t_ns: np.ndarray, factor: float = 3.0) -> list[list[float]]:
    """Time ranges with no sample: ``[start_s, end_s]`` (mission seconds) between consecutive
    samples more than ``factor`` periods apart (lost chunks, a dropped sensor); see
    :func:`~impala_eval.metrics.gap_spans_ns` for the period (repeated stamps count once)."""
    return [[round(float(a) * 1e-9, 6), round(float(b) * 1e-9, 6)] for a, b in gap_spans_ns(t_ns, factor).tolist()]


def gap_summary(gaps: dict[str, list[list[float]]]) -> str:
    """One line: per stream the number of gaps, their total and the longest (where)."""
    parts = []
    for stream, ranges in gaps.items():
        if not ranges:
            continue
        spans = [b - a for a, b in ranges]
        k = int(np.argmax(spans))
        parts.append(f"{stream} {len(ranges)} gap{'s' if len(ranges) > 1 else ''} ({sum(spans):.2f} s in all, "
                     f"longest {spans[k]:.2f} s at t={ranges[k][0]:.3f} s)")
    return "; ".join(parts)


def _gap_text(figures: dict[str, Any]) -> str:
    return gap_summary(figures.get("gaps") or {})


def new_figure(w: float, h: float):  # type: ignore[no-untyped-def]
    """A matplotlib Figure of ``w`` x ``h`` inches on the Agg backend (matplotlib imported here, lazily)."""
    import matplotlib

    matplotlib.use("Agg", force=False)
    from matplotlib.figure import Figure

    return Figure(figsize=(w, h), dpi=110, layout="constrained")


def save_figure(fig, path: str | Path) -> None:  # type: ignore[no-untyped-def]
    """Write ``fig`` (from :func:`new_figure`) as a PNG, drawn once. ``Figure.savefig`` draws a
    constrained-layout figure twice (a draw with rendering off to lay it out, then the drawn one,
    which lays it out again): the same pixels for about 0.75 of the time. zlib level 3 instead of
    PIL's 6: the same pixels, encoded in 0.6 of the time, and the reports' PNGs 3.5 % smaller."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    FigureCanvasAgg(fig).print_png(str(path), pil_kwargs={"compress_level": 3})


def _map_image(grid: Grid, scale: str = "db") -> tuple[np.ndarray, list[float]]:
    """Map intensities in dB (``scale = "db"``: the values are dB already, R-SLAM's map;
    ``"power"``: 10 log10 above the 5th percentile), NaN where unmapped; imshow extent (m)."""
    data = np.asarray(grid.data, np.float64)
    if scale == "db":
        img = np.where(data > 0, data, np.nan)
    else:
        seen = data[data > 0]
        floor = float(np.percentile(seen, 5)) if seen.size else 1.0
        img = np.where(data > 0, 10.0 * np.log10(np.maximum(data, floor) / floor), np.nan)
    h, w = data.shape
    c = grid.cell_m
    return img, [grid.origin_x_m - c / 2, grid.origin_x_m + (w - 0.5) * c,
                 grid.origin_y_m - c / 2, grid.origin_y_m + (h - 0.5) * c]


def show_map(ax, grid: Grid, transform: tuple[np.ndarray, np.ndarray] | None = None,  # type: ignore[no-untyped-def]
             scale: str = "db") -> None:
    """Draw the radar map ``grid`` under a figure's trajectories on ``ax`` (in dB or linear power),
    moved by ``transform`` (rotation, translation) when the trajectories were aligned."""
    import matplotlib.transforms as mtransforms

    img, extent = _map_image(grid, scale)
    finite = np.isfinite(img)
    vmin, vmax = (np.nanpercentile(img, [2.0, 99.5]) if finite.any() else (0.0, 1.0))
    im = ax.imshow(img, origin="lower", extent=extent, cmap="gray", vmin=float(vmin),
                   vmax=max(float(vmax), float(vmin) + 1e-6), interpolation="antialiased")
    if transform is not None:  # map frame -> truth frame (the alignment of the estimate)
        r, t = transform
        aff = mtransforms.Affine2D(np.array([[r[0, 0], r[0, 1], t[0]], [r[1, 0], r[1, 1], t[1]], [0, 0, 1]]))
        im.set_transform(aff + ax.transData)
    label = "radar map amplitude (dB)" if scale == "db" else "radar map intensity (dB above floor)"
    ax.figure.colorbar(im, ax=ax, shrink=0.8, label=label)


def _ate_label(m: TrajectoryMetrics) -> str:
    pct = m.ate_pct
    return f"ATE {m.ate_rmse_m:.2f} m" + (f" = {pct:.2f} % of {m.path_length_m:.0f} m" if pct is not None else "")


def write_report(folder: str | Path, figures: dict[str, Any], est: TrajectoryMetrics,
                 baseline: TrajectoryMetrics | None = None, radar_map: Grid | None = None,
                 transform: tuple[np.ndarray, np.ndarray] | None = None, title: str = "R-SLAM",
                 map_scale: str = "db", baseline_title: str = "dead reckoning", pairs_figure: bool = False,
                 twist: TwistErrors | None = None) -> Path:
    """Write the report folder (see the module doc); return its path. ``map_scale``: the
    map's values are dB (R-SLAM's map) or linear power."""
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    (folder / METRICS_FILE).write_text(json.dumps(figures, indent=2, sort_keys=True) + "\n")

    # Fig. 12: the estimate's error on its own scale; below it, beside the baseline's when
    # that one is much larger (dead reckoning drifts tens of metres where R-SLAM stays cm)
    apart = baseline is not None and float(np.max(baseline.error_m)) > 3.0 * max(float(np.max(est.error_m)), 1e-6)
    fig = new_figure(8.0, 6.4 if apart else 3.6)
    axes = fig.subplots(2, 1, sharex=True) if apart else [fig.add_subplot()]
    for i, ax in enumerate(axes):
        if baseline is not None and (i == 1 or not apart):
            ax.plot(baseline.distance_m, baseline.error_m, color=_BASE, lw=1.2,
                    label=f"{baseline_title} (ATE RMSE {baseline.ate_rmse_m:.2f} m)")
        ax.plot(est.distance_m, est.error_m, color=_EST, lw=1.4,
                label=f"{title} (ATE RMSE {est.ate_rmse_m:.3f} m" + (
                    f", final drift {est.drift_pct:.2f} %)" if est.drift_pct is not None else ")"))
        ax.set(ylabel="position error (m)")
        ax.set_xlim(0, max(est.distance_m[-1], 1e-3))
        ax.set_ylim(0, 1.3 * max(max((float(np.max(ln.get_ydata())) for ln in ax.get_lines()), default=0.0), 1e-6))
        ax.grid(alpha=0.3)
        ax.legend(loc="upper left", frameon=False)  # above the curves: 30 % headroom
    axes[0].set_title(f"Position error vs truth after {est.align} alignment"
                      + (f" ({title} alone, then beside the baseline)" if apart else ""))
    axes[-1].set_xlabel("distance travelled (m)")
    if _gap_text(figures):  # the metrics cover only what was received: say what was not
        import textwrap  # below the plot (not over the curves and the legend), wrapped to its width

        fig.supxlabel("\n".join(textwrap.wrap("DATA MISSING: " + _gap_text(figures), 130)), color="#d62728",
                      fontsize=8)
    save_figure(fig, folder / "error_vs_distance.png")

    fig = new_figure(7.5, 7.0)
    ax = fig.add_subplot()
    if radar_map is not None:
        show_map(ax, radar_map, transform, map_scale)
    ax.plot(est.truth_xyt[:, 0], est.truth_xyt[:, 1], color=_TRUTH, lw=2.2, alpha=0.8, label="truth")
    if baseline is not None:
        ax.plot(baseline.est_aligned_xyt[:, 0], baseline.est_aligned_xyt[:, 1], color=_BASE, lw=1.2,
                ls="--", label=f"{baseline_title} ({_ate_label(baseline)})")
    ax.plot(est.est_aligned_xyt[:, 0], est.est_aligned_xyt[:, 1], color=_EST, lw=1.2,
            label=f"{title} ({_ate_label(est)})")
    ax.plot(*est.est_aligned_xyt[-1, :2], "x", color=_EST, ms=8, mew=2.0, zorder=6)
    ax.plot(*est.truth_xyt[0, :2], "o", color="k", mfc="w", ms=7, mew=1.5, label="start", zorder=6)
    ax.plot(*est.truth_xyt[-1, :2], "s", color="k", mfc="w", ms=7, mew=1.5, label="end (x: the estimate's)",
            zorder=6)
    xy = np.vstack([est.truth_xyt[:, :2], est.est_aligned_xyt[:, :2]])
    lo, hi = xy.min(axis=0), xy.max(axis=0)
    pad = 0.15 * float(max(hi - lo)) + 5.0
    half = 0.5 * (hi - lo) + pad
    half = np.maximum(half, 0.6 * half.max())  # a straight path keeps some map either side
    mid = 0.5 * (hi + lo)
    ax.set_xlim(mid[0] - half[0], mid[0] + half[0])
    ax.set_ylim(mid[1] - half[1], mid[1] + half[1])
    ax.set_aspect("equal")
    ax.set(xlabel="x (m)", ylabel="y (m)", title=f"{title} trajectory over the radar map")
    ax.legend(loc="best", framealpha=0.85)
    save_figure(fig, folder / "trajectory_map.png")

    if pairs_figure and len(est.pairs.t_ns):
        _pairs_figure(folder / "pair_errors.png", est, baseline, title, baseline_title)
    if twist is not None and len(twist.t_ns):
        _twist_figure(folder / "twist_errors.png", twist, title)
    if radar_map is not None:
        fig = new_figure(7.5, 7.0)
        ax = fig.add_subplot()
        show_map(ax, radar_map, scale=map_scale)
        ax.set_aspect("equal")
        ax.set(xlabel="x (m, map frame)", ylabel="y (m, map frame)",
               title=f"Radar map ({radar_map.cell_m:.2f} m cells, eq. 6)")
        save_figure(fig, folder / "map.png")
    return folder


def _twist_figure(path: Path, tw: TwistErrors, title: str) -> None:
    """True speed and yaw rate (top), the estimate's errors against time (bottom)."""
    t = (tw.t_ns - tw.t_ns[0]) * 1e-9
    f = tw.figures()
    fig = new_figure(9.0, 6.0)
    (a, b), (c, d) = fig.subplots(2, 2, sharex=True)
    a.plot(t, tw.truth_speed_mps, color=_TRUTH, lw=1.2)
    a.set(ylabel="true speed (m/s)", title="speed")
    ty = t[tw.yaw_known]
    b.plot(ty, tw.truth_yaw_rate_dps, color=_TRUTH, lw=1.2)
    b.set(ylabel="true yaw rate (deg/s)", title="yaw rate")
    c.plot(t, tw.speed_err_mps, ".", color=_EST, ms=3)
    c.set(xlabel="time (s)", ylabel="error (m/s)",
          title=f"mean {f['speed_err_mean_mps']:+.3f}, std {f['speed_err_std_mps']:.3f} m/s")
    d.plot(ty, tw.yaw_rate_err_dps, ".", color=_EST, ms=3)
    skipped = f", {f['twist_heading_unknown']} where the truth heading is unknown left out" \
        if f["twist_heading_unknown"] else ""
    d.set(xlabel="time (s)", ylabel="error (deg/s)",
          title=(f"mean {f['yaw_rate_err_mean_dps']:+.3f}, std {f['yaw_rate_err_std_dps']:.3f} deg/s"
                 if len(ty) else "no yaw rate scored (truth heading unknown)") + skipped)
    for ax in (a, b, c, d):
        ax.grid(alpha=0.3)
    for ax in (c, d):
        ax.axhline(0.0, color="k", lw=0.6)
    fig.suptitle(f"{title}: estimate - truth (truth over {tw.window_s:g} s windows)")
    save_figure(fig, path)


def _bars(ax: Any, k: np.ndarray, edges: np.ndarray, vals: np.ndarray, width: float, style: dict) -> None:
    """One bar per pair; past 60 pairs one filled step outline instead (a bar per pair is one
    artist each: 400 pairs took 1.6 s to draw, and the bars no longer show apart anyway)."""
    if len(k) <= 60:
        ax.bar(k, vals, width=width, **style)
    else:
        ax.stairs(vals, edges, fill=True, **style)


def _pairs_figure(path: Path, est: TrajectoryMetrics, baseline: TrajectoryMetrics | None, title: str,
                  baseline_title: str) -> None:
    """Per-pair translation (cm) and rotation (deg) errors, the baseline's as light bars."""
    p = est.pairs
    k = np.arange(1, len(p.t_ns) + 1)
    fig = new_figure(8.0, 6.0)
    axes = fig.subplots(3, 1, sharex=True)
    series = [(p.trans_err_m * 100.0, "translation error (cm)", f"mean {100 * p.trans_err_m.mean():.1f} cm"),
              (p.rot_err_deg, "rotation error (deg)", f"mean {p.rot_err_deg.mean():.3f} deg"),
              (p.lateral_err_m * 100.0, "signed error (cm)", "")]
    base = baseline.pairs if baseline is not None and len(baseline.pairs.t_ns) == len(p.t_ns) else None
    edges = np.arange(len(k) + 1) + 0.5  # pair i's bar spans i +- 0.5
    for i, (ax, (vals, label, note)) in enumerate(zip(axes, series, strict=True)):
        if i < 2:
            if base is not None:
                bvals = base.trans_err_m * 100.0 if i == 0 else base.rot_err_deg
                _bars(ax, k, edges, bvals, 0.8, dict(color=_BASE, alpha=0.25,
                                                     label=f"{baseline_title} (mean {bvals.mean():.2f})"))
                ax.set_ylim(0, 1.3 * max(float(vals.max()), 1e-6) + 1e-6)
            _bars(ax, k, edges, vals, 0.5, dict(color=_EST, label=f"{title} ({note})"))
        else:
            ax.plot(k, p.along_err_m * 100.0, "o-", color="#9467bd", label="along track (x, forward)")
            ax.plot(k, vals, "s-", color="#ff7f0e", label="lateral (y, left)")
            ax.axhline(0.0, color="k", lw=0.6)
        ax.set_ylabel(label)
        ax.grid(alpha=0.3)
        ax.legend(loc="upper left", frameon=False, fontsize=8)
    axes[0].set_title(f"Scan-to-scan relative-motion error against the truth ({len(k)} pairs)")
    axes[-1].set_xlabel("pair (consecutive estimates)")
    save_figure(fig, path)


def _cell(v: Any) -> str:
    return "n/a" if v is None or (isinstance(v, float) and not math.isfinite(v)) else f"{v:.3f}"


def format_metrics(figures: dict[str, Any]) -> str:
    """Human-readable lines: estimate and baseline side by side; the relative drift per
    segment length, what the truth heading left unscored and the data missing, one line each."""
    rows = [("ATE RMSE", "ate_rmse_m", "m"), ("ATE RMSE / path", "ate_pct", "% of path"),
            ("ATE mean", "ate_mean_m", "m"), ("ATE max", "ate_max_m", "m"),
            ("heading RMSE", "heading_rmse_deg", "deg"), ("rel. error / 100 m", "rel_err_per_100m_pct", "%"),
            ("drift 100-800 m", "rel_err_pct", "% (KITTI, mean over segments)"),
            ("final error", "final_error_m", "m"), ("final drift", "drift_pct", "% of path"),
            ("path length", "path_length_m", "m"), ("pair error mean", "pair_trans_err_mean_m", "m"),
            ("pair error max", "pair_trans_err_max_m", "m"), ("pair rotation mean", "pair_rot_err_mean_deg", "deg"),
            ("pair rotation max", "pair_rot_err_max_deg", "deg")]
    has_base = any(k.startswith("baseline_") for k in figures)
    head = f"{'':22s}{'estimate':>12s}" + (f"{'baseline':>12s}" if has_base else "")
    lines = [head]
    for label, key, unit in rows:
        vals = [figures.get(key)] + ([figures.get("baseline_" + key)] if has_base else [])
        lines.append(f"{label:22s}{''.join(f'{_cell(v):>12s}' for v in vals)}  {unit}")
    by_length = sorted((float(k[8:-5]), k) for k in figures if k.startswith("rel_err_") and k.endswith("m_pct")
                       and k[8:-5].replace(".", "", 1).isdigit())
    if by_length:
        lines.append("drift per segment length: " + ", ".join(
            f"{L:g} m {figures[k]:.2f} % (n={figures.get(k[:-4] + '_segments', '?')})" for L, k in by_length))
    elif figures.get("rel_err_segments") == 0:
        lines.append("drift per segment length: no segment (path shorter than 100 m or no known truth heading)")
    unknown = figures.get("n_heading_unknown") or 0
    if unknown:
        skipped = figures.get("n_pairs_heading_unknown") or 0
        lines.append(f"truth heading unknown at {unknown} of {figures.get('n_poses')} poses: heading, rotation, "
                     f"relative errors there left out ({skipped} pairs); ATE over all (positions)"
                     + (f"; first-pose alignment on pose {figures['first_aligned_pose']}"
                        if figures.get("first_aligned_pose") else ""))
    if figures.get("n_poses_in_truth_gaps"):
        lines.append(f"{figures['n_poses_in_truth_gaps']} estimated poses inside gaps of the truth: left out")
    if _gap_text(figures):
        lines.append(f"DATA MISSING (no sample): {_gap_text(figures)}; the metrics cover only what was received")
    return "\n".join(lines)


def load_metrics(folder: str | Path) -> dict[str, Any]:
    return json.loads((Path(folder) / METRICS_FILE).read_text())
