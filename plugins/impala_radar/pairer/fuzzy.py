"""Fuzzy scoring of candidate up/down peak pairs (seed 1 §2.4: four criteria, six rules).

Criteria of a candidate pair (up peak u, down peak d) of one beam:

- **position**: ``|(b_u - b_d) - e|`` in bins, ``e`` the offset expected for a static target
  at this azimuth (2 f_d / bin_hz from the ego-speed prior, 0 without one): the seed's
  "relative position" criterion favours close peaks;
- **amplitude**: ``|10 log10(P_u / P_d)|`` dB (same target, same power on both ramps);
- **width**: ``|ln(w_u / w_d)|`` of the -3 dB widths (same spectral occupation);
- **symmetry**: ``min(s_u, s_d)``, each peak's half-width ratio (Gaussian envelope = 1).

Memberships are trapezoid shoulders ``ramp(x, full, zero)``: 1 up to ``full``, 0 from
``zero``, linear between (a rising shoulder when ``full > zero``). Defaults
(:data:`DEFAULT_MEMBERSHIP`, overridable by the ``membership`` parameter)::

    NEAR      position  <= 1.0 bin -> 1, >= 3.0 bins -> 0        FAR = 1 - NEAR
    SIMILAR_A amplitude <= 2.0 dB  -> 1, >= 6.0 dB   -> 0        DIFFERENT_A = 1 - SIMILAR_A
    SIMILAR_W width     <= 0.2     -> 1, >= 0.7      -> 0        DIFFERENT_W = 1 - SIMILAR_W
    SYMMETRIC symmetry  >= 0.8     -> 1, <= 0.4      -> 0        ASYMMETRIC = 1 - SYMMETRIC

Six IF...THEN rules (AND = min, OR = max, NOT = 1 - x), zero-order Sugeno: the score is the
firing-strength-weighted mean of the rule outputs (:data:`DEFAULT_RULES`, overridable):

    R1 IF NEAR AND SIMILAR_A                           THEN 1.00 (static target, sure)
    R2 IF NEAR AND (SIMILAR_W OR SYMMETRIC)            THEN 0.75
    R3 IF SIMILAR_A AND SIMILAR_W AND SYMMETRIC        THEN 0.70 (mover: position free)
    R4 IF FAR AND SIMILAR_A                            THEN 0.50
    R5 IF DIFFERENT_A                                  THEN 0.00
    R6 IF FAR AND (DIFFERENT_W OR ASYMMETRIC)          THEN 0.00

Rules are given as ``[output, [term, ...], [term, ...], ...]``: the AND of groups, each
group the OR of its terms (a term prefixed ``not `` is complemented). Hand-written and
vectorised over all pairs of a turn: scikit-fuzzy evaluates one crisp input at a time
through Python loops, orders of magnitude slower for the ~10^4-10^5 pairs of a turn.
"""

from __future__ import annotations

import numpy as np

__all__ = ["DEFAULT_MEMBERSHIP", "DEFAULT_RULES", "ramp", "memberships", "pair_score"]

DEFAULT_MEMBERSHIP: dict[str, list[float]] = {
    "near": [1.0, 3.0],        # position offset, bins
    "similar_a": [2.0, 6.0],   # amplitude ratio, dB
    "similar_w": [0.2, 0.7],   # |ln width ratio|
    "symmetric": [0.8, 0.4],   # min symmetry (rising: full at 0.8, zero at 0.4)
}

DEFAULT_RULES: list[list] = [
    [1.00, ["near"], ["similar_a"]],
    [0.75, ["near"], ["similar_w", "symmetric"]],
    [0.70, ["similar_a"], ["similar_w"], ["symmetric"]],
    [0.50, ["not near"], ["similar_a"]],
    [0.00, ["not similar_a"]],
    [0.00, ["not near"], ["not similar_w", "not symmetric"]],
]


def ramp(x: np.ndarray, full: float, zero: float) -> np.ndarray:
    """Shoulder membership: 1 at ``full``, 0 at ``zero``, linear in between, clipped."""
    return np.clip((np.asarray(x, float) - zero) / (full - zero), 0.0, 1.0)


def memberships(position_bins, amplitude_db, width_log, symmetry,
                membership: dict[str, list[float]] | None = None) -> dict[str, np.ndarray]:
    """Degrees of the four base terms for crisp criterion values."""
    m = {**DEFAULT_MEMBERSHIP, **(membership or {})}
    return {
        "near": ramp(position_bins, *m["near"]),
        "similar_a": ramp(amplitude_db, *m["similar_a"]),
        "similar_w": ramp(width_log, *m["similar_w"]),
        "symmetric": ramp(symmetry, *m["symmetric"]),
    }


def _term(mu: dict[str, np.ndarray], term: str) -> np.ndarray:
    if term.startswith("not "):
        return 1.0 - mu[term[4:].strip()]
    return mu[term]


def pair_score(position_bins, amplitude_db, width_log, symmetry,
               membership: dict[str, list[float]] | None = None,
               rules: list[list] | None = None) -> np.ndarray:
    """Fuzzy pairing score in [0, 1] of each candidate pair (zero-order Sugeno inference)."""
    mu = memberships(position_bins, amplitude_db, width_log, symmetry, membership)
    num = np.zeros(np.shape(position_bins))
    den = np.full(np.shape(position_bins), 1e-9)
    for rule in rules or DEFAULT_RULES:
        out, groups = float(rule[0]), rule[1:]
        strength = None
        for group in groups:
            g = _term(mu, group[0])
            for t in group[1:]:
                g = np.maximum(g, _term(mu, t))
            strength = g if strength is None else np.minimum(strength, g)
        num += strength * out
        den += strength
    return num / den
