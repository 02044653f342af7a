"""A report figure is drawn once (report.save_figure) and gives Figure.savefig's pixels."""

from __future__ import annotations

import numpy as np
from PIL import Image

from impala_eval.report import new_figure, save_figure, show_map
from impala_flow.msgs import Grid


def _figure():  # type: ignore[no-untyped-def]
    """What the reports draw: constrained layout, a map with NaN holes under a colorbar, lines,
    markers, a legend, a wrapped figure label."""
    rng = np.random.default_rng(5)
    data = rng.gamma(2.0, 3.0, (300, 400)).astype(np.float32)
    data[:40, :] = 0.0  # unmapped: NaN in the image
    fig = new_figure(7.5, 7.0)
    ax, ax2 = fig.subplots(2, 1)
    show_map(ax, Grid(data=data, cell_m=0.2, origin_x_m=-40.0, origin_y_m=-30.0))
    s = np.linspace(0.0, 60.0, 400)
    ax.plot(s - 30.0, 10.0 * np.sin(s / 9.0), color="#d62728", lw=1.2, label="estimate")
    ax.plot(-30.0, 0.0, "o", color="k", mfc="w", ms=7, label="start")
    ax.set_aspect("equal")
    ax.legend(loc="best", framealpha=0.85)
    ax2.stairs(rng.random(400), np.arange(401) + 0.5, fill=True, color="#1f77b4", alpha=0.25, label="pairs")
    ax2.legend(loc="upper left", frameon=False, fontsize=8)
    fig.supxlabel("DATA MISSING: truth 2 gaps (1.20 s in all)", color="#d62728", fontsize=8)
    return fig


def test_save_figure_gives_savefig_pixels(tmp_path):
    _figure().savefig(tmp_path / "savefig.png")
    save_figure(_figure(), tmp_path / "once.png")
    want = np.asarray(Image.open(tmp_path / "savefig.png"))
    got = np.asarray(Image.open(tmp_path / "once.png"))
    assert got.shape == want.shape == (770, 825, 4)  # 7.5 x 7.0 in at 110 dpi
    assert np.array_equal(got, want)
