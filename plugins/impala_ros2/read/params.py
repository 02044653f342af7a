"""The options of the ROS 2 adapters (``io.Replayer``'s ``adapter_params``, ``import ros2 --config KEY=VALUE``)."""

from __future__ import annotations

import math
from typing import Any

__all__ = ["PARAMS", "check_params"]

#: key -> (kind, low, high, meaning); numbers bounded (low exclusive when kind is "float>")
PARAMS: dict[str, tuple[str, float, float, str]] = {
    "range_resolution_m": ("float>", 0.0, 10.0, "range per bin (m); default: Navtech's configuration message"),
    "range_offset_bins": ("float", -1000.0, 1000.0, "range of bin 0 in bins (default 0.5: bin centres, as the "
                          "direct Oxford/RADIATE import)"),
    "rotation": ("choice", 0, 0, "clockwise (Navtech, default) or counterclockwise: the antenna's turn"),
    "rotation_hz": ("float>", 0.0, 100.0, "turns per second; default: measured on the first 20 stamps (median "
                    "interval, to 1 mHz, as the direct import), else the configuration message's"),
    "azimuth_offset_deg": ("float", -360.0, 360.0, "constant added to every azimuth, counter-clockwise positive "
                           "(default 0; the direct import's are oxford -0.95, radiate -2.3)"),
    "db_per_count": ("float>", 0.0, 1.0, "log scale of the 8-bit counts: power 10^(count x DB / 10) (default 0.5)"),
    "encoder_size": ("int", 1, 65535, "encoder counts per turn of FFT-data messages (default: configuration)"),
    "beams_per_turn": ("int", 1, 65535, "azimuths per turn of FFT-data messages (default: configuration)"),
    "sensor": ("str", 0, 0, "radar name carried by every beam's RadarConfig (default navtech-ros2)"),
}
ROTATIONS = ("clockwise", "counterclockwise")


def check_params(params: dict[str, Any]) -> dict[str, Any]:
    """The options as numbers, or ValueError naming the key and what is wrong (strings from the command line
    are parsed)."""
    out: dict[str, Any] = {}
    for key, raw in params.items():
        if key not in PARAMS:
            raise ValueError(f"unknown option {key!r} (known: {', '.join(PARAMS)})")
        kind, lo, hi, _ = PARAMS[key]
        if kind == "choice":
            if str(raw) not in ROTATIONS:
                raise ValueError(f"{key}: {raw!r} is not one of {', '.join(ROTATIONS)}")
            out[key] = str(raw)
            continue
        if kind == "str":
            out[key] = str(raw)
            continue
        try:
            value = int(raw) if kind == "int" else float(raw)
        except (TypeError, ValueError):
            raise ValueError(f"{key}: {raw!r} is not a{'n integer' if kind == 'int' else ' number'}") from None
        if not (math.isfinite(value) and (lo < value if kind == "float>" else lo <= value) and value <= hi):
            raise ValueError(f"{key}: {raw!r} out of range ({'(' if kind == 'float>' else '['}{lo:g}, {hi:g}])")
        out[key] = value
    return out
