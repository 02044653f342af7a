"""``radar.FrontendReport``: the component (ports, parameters, sample handling). The algorithm, and
what it follows, is described in :mod:`impala_radar.report.core`.
"""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:  # matplotlib (0.4 s) loads when a report is drawn, not at each command's start
    from matplotlib.figure import Figure

from impala_flow import Component, Input, Param
from impala_flow.msgs import Grid
from impala_msgs import RadarBeam, RadarDetections, Speed

from ..ego_velocity.core import fit_ego_velocity, radial_speed_model_mps
from .core import beat_bins_of_detections

__all__ = ["FrontendReport"]


def _db(x: np.ndarray) -> np.ndarray:
    return 10.0 * np.log10(np.maximum(np.asarray(x, float), 1e-30))



def _figure(figsize: tuple[float, float]) -> Figure:
    from matplotlib.figure import Figure

    return Figure(figsize=figsize, layout="constrained")

class FrontendReport(Component):
    """Keeps the last complete turn of beams and its detections, the last speed estimate
    and the last raw and filtered images; writes the three figures into ``path`` at stop."""

    beams = Input(RadarBeam, maxsize=8192, required=False, doc="beams (spectra of the shown beam)")
    detections = Input(RadarDetections, required=False, doc="pairer output")
    speed = Input(Speed, policy="sampling", required=False, doc="ego-velocity estimate")
    image = Input(Grid, policy="sampling", required=False, doc="panoramic image before filtering")
    filtered = Input(Grid, policy="sampling", required=False, doc="panoramic image after filtering")

    path = Param(str, default="out/frontend", path="write_dir", doc="folder of the PNG files")
    beam = Param(int, default=-1, ge=-1, doc="beam shown in pairs.png (-1: the one with most pairs)")
    dpi = Param(int, default=110, ge=30)
    extent_m = Param(float, default=60.0, gt=0, doc="half side of the PPI plots")

    def start(self) -> None:
        self._turn_beams: list[RadarBeam] = []
        self._full: dict[int, list[RadarBeam]] = {}
        self._dets: dict[int, RadarDetections] = {}
        self.written: list[str] = []

    def process(self, t: int) -> None:
        if self.trigger == "beams":
            b: RadarBeam = self.beams.take()
            if self._turn_beams and b.turn != self._turn_beams[-1].turn:
                self._turn_beams = []
            self._turn_beams.append(b)
            if b.index == b.config.beams_per_turn - 1:
                self._full = {b.turn: self._turn_beams, **{k: v for k, v in self._full.items() if k >= b.turn - 2}}
                self._turn_beams = []
        elif self.trigger == "detections":
            d: RadarDetections = self.detections.take()
            self._dets = {d.turn: d, **{k: v for k, v in self._dets.items() if k >= d.turn - 2}}

    def stop(self) -> None:
        if not hasattr(self, "_dets"):
            return
        out = Path(self.path)
        out.mkdir(parents=True, exist_ok=True)
        both = sorted(set(self._full) & set(self._dets))
        if self.image.get() is not None:
            self._ppi(out / "ppi.png")
        if self._dets:
            self._doppler(out / "doppler.png", self._dets[max(self._dets)])
        if both:
            self._pairs(out / "pairs.png", self._full[both[-1]], self._dets[both[-1]])

    def _save(self, fig: Figure, path: Path) -> None:
        from matplotlib.backends.backend_agg import FigureCanvasAgg

        FigureCanvasAgg(fig)
        fig.savefig(path, dpi=self.dpi)
        self.written.append(str(path))

    def _ppi(self, path: Path) -> None:
        grids = [("panoramic image (one turn)", self.image.get()),
                 ("after multi-look anti-speckle filter", self.filtered.get())]
        grids = [(n, g) for n, g in grids if g is not None]
        fig = _figure((5.2 * len(grids), 5.0))
        axes = fig.subplots(1, len(grids), squeeze=False)[0]
        obs = grids[0][1].data[grids[0][1].data > 0]
        lo, hi = (np.percentile(_db(obs), [5, 99.9]) if obs.size else (-150, -100))
        e = self.extent_m
        for ax, (name, g) in zip(axes, grids, strict=True):
            h, w = g.data.shape
            ext = [g.origin_x_m - g.cell_m / 2, g.origin_x_m + (w - 0.5) * g.cell_m,
                   g.origin_y_m - g.cell_m / 2, g.origin_y_m + (h - 0.5) * g.cell_m]
            im = ax.imshow(_db(g.data), origin="lower", extent=ext, cmap="inferno", vmin=lo, vmax=hi,
                           interpolation="nearest")
            ax.set_xlim(-e, e)
            ax.set_ylim(-e, e)
            ax.plot(0, 0, "c+", ms=10)
            ax.set_title(name, fontsize=10)
            ax.set_xlabel("x forward (m)")
            ax.set_ylabel("y left (m)")
        fig.colorbar(im, ax=axes, shrink=0.8, label="power (dBW)")
        fig.suptitle("PPI, vehicle frame at the turn's last beam (cf. seed 1 Fig. 3)")
        self._save(fig, path)

    def _doppler(self, path: Path, d: RadarDetections) -> None:
        fit = fit_ego_velocity(d.azimuth_rad, d.radial_speed_mps)
        fig = _figure((8, 4.5))
        ax = fig.subplots()
        az_deg = np.degrees(np.mod(d.azimuth_rad, 2 * np.pi))
        if fit is not None:
            ax.plot(az_deg[fit.inlier], d.radial_speed_mps[fit.inlier], ".", ms=3, color="0.35",
                    label=f"static ({fit.inlier.sum()})")
            ax.plot(az_deg[~fit.inlier], d.radial_speed_mps[~fit.inlier], "o", ms=4, mfc="none",
                    color="tab:red", label=f"off the curve: movers, ghosts ({(~fit.inlier).sum()})")
            th = np.linspace(0, 2 * np.pi, 361)
            ax.plot(np.degrees(th), radial_speed_model_mps(th, fit.v0_mps, fit.theta0_rad), "-",
                    color="tab:blue", lw=2,
                    label=f"V0 cos(θ-θ0): V0 = {fit.v0_mps:.2f} m/s, θ0 = {np.degrees(fit.theta0_rad):.1f}°")
        est = self.speed.get()
        title = f"turn {d.turn}: radial speed against azimuth (cf. seed 1 Fig. 17)"
        if est is not None:
            title += f" — speed {est.speed_mps:.2f} ± {est.std_mps:.2f} m/s"
        ax.set_title(title, fontsize=10)
        ax.set_xlabel("azimuth θ from the heading (deg)")
        ax.set_ylabel("radial speed V (m/s, < 0 approaching)")
        ax.set_xlim(0, 360)
        ax.set_xticks(range(0, 361, 45))
        ax.grid(alpha=0.3)
        ax.legend(fontsize=8, loc="upper center", bbox_to_anchor=(0.5, -0.14), ncol=3, frameon=False)
        self._save(fig, path)

    def _pairs(self, path: Path, beams: list[RadarBeam], d: RadarDetections) -> None:
        config = beams[0].config
        counts = np.bincount(d.beam, minlength=len(beams))
        # default: the beam with most pairs where the static Doppler shift shows (|cos| >= 0.7)
        az = np.array([x.azimuth_rad for x in beams])
        k = self.beam if 0 <= self.beam < len(beams) else int(np.argmax(counts * (np.abs(np.cos(az)) >= 0.7)))
        b = beams[k]
        sel = d.beam == k
        bu, bd = beat_bins_of_detections(d.range_m[sel], d.radial_speed_mps[sel], config)
        fig = _figure((9, 4.8))
        ax = fig.subplots()
        bins = np.arange(len(b.up))
        up_db, down_db = _db(b.up), _db(b.down)
        ax.plot(bins, up_db, color="tab:blue", lw=1, label="up ramp  (f_r + f_d)")
        ax.plot(bins, down_db, color="tab:orange", lw=1, label="down ramp (f_r - f_d)")
        order = np.argsort(bu)
        for n, i in enumerate(order):
            yu = np.interp(bu[i], bins, up_db)
            yd = np.interp(bd[i], bins, down_db)
            ax.plot([bu[i], bd[i]], [yu + 2, yd + 2], "k-", lw=0.8)
            ax.plot(bu[i], yu + 2, "v", color="tab:blue")
            ax.plot(bd[i], yd + 2, "v", color="tab:orange")
            label = chr(ord("A") + n % 26)
            ax.annotate(f"{label}: {d.range_m[sel][i]:.1f} m, {d.radial_speed_mps[sel][i]:+.1f} m/s",
                        (0.5 * (bu[i] + bd[i]), max(yu, yd) + 4), ha="center", fontsize=7)
        top = max(up_db.max(), down_db.max())
        ax.set_ylim(top - 70, top + 12)
        ax.set_xlim(0, len(bins) - 1)
        ax.set_xlabel(f"beat frequency bin ({config.bin_hz:.0f} Hz, {config.range_per_bin_m:.3f} m at V = 0)")
        ax.set_ylabel("power (dBW)")
        ax.set_title(f"turn {b.turn}, beam {k} (azimuth {np.degrees(b.azimuth_rad):.1f}°): "
                     f"{sel.sum()} fuzzy pairs (cf. seed 1 Fig. 4)", fontsize=10)
        ax.grid(alpha=0.3)
        ax.legend(fontsize=8, loc="lower left")
        self._save(fig, path)
