"""Compiled loops of the simulator's synthesis (:class:`.spectra.Synthesizer`): each ramp's
echoes prepared for the NUFFT (:func:`ramp_echoes`: beat frequency, phase mod 2 pi, the
kernel's exponents), the spreading onto the grid and its fold (:func:`spread_fold`), the
ramp's samples and bin powers (:func:`windowed_samples`, :func:`bin_powers`), and the older
single-purpose loops (:func:`grid_positions`, :func:`kernel_arguments`, :func:`spread`,
:func:`wrap_phase32`) of :meth:`.spectra.Synthesizer.signal`.

As in :mod:`.kernels` (cached numba, imported at the first call): the arithmetic of the numpy
formulation, in its order and float types; the kernel's exponential and the phasors' cosines
stay numpy's; the remainders are numpy's (with an exact fmod-free mod 2 pi); the float64 sums
onto the grid run in the order ``np.bincount`` used.
"""

from __future__ import annotations

import math

import numba
import numpy as np

from .kernels import remainder

__all__ = ["grid_positions", "kernel_arguments", "spread", "wrap_phase32", "ramp_echoes", "spread_fold",
           "windowed_samples", "bin_powers", "skirt_select"]


@numba.njit(cache=True, nogil=True)
def grid_positions(f_hz, scale, m_grid):
    """``(f_hz * scale) % m_grid``: each echo's position on the spreading grid, in [0, M)."""
    out = np.empty(f_hz.shape[0])
    for i in range(f_hz.shape[0]):
        out[i] = remainder(f_hz[i] * scale, m_grid)
    return out


@numba.njit(cache=True, nogil=True)
def wrap_phase32(phase_rad):
    """``(phase % 2 pi).astype(float32)``."""
    out = np.empty(phase_rad.shape[0], np.float32)
    for i in range(phase_rad.shape[0]):
        out[i] = np.float32(_mod_2pi(phase_rad[i]))
    return out


@numba.njit(cache=True, nogil=True)
def kernel_arguments(x, beam, row, offsets, u_scale, beta):
    """The exponent beta (sqrt(1 - u^2) - 1) of the ES kernel at the grid points around each
    echo (float32, (n, width)) and the flat index of each echo's first grid point."""
    n, width = x.shape[0], offsets.shape[0]
    arg = np.empty((n, width), np.float32)
    base = np.empty(n, np.intp)
    one = np.float32(1.0)
    zero = np.float32(0.0)
    for i in range(n):
        i0 = math.floor(x[i])
        frac = np.float32(x[i] - i0)
        base[i] = np.intp(beam[i]) * row + np.intp(i0)
        for k in range(width):
            u = (offsets[k] - frac) * u_scale
            v = one - u * u
            if not v >= zero:  # np.maximum(v, 0)
                v = zero
            arg[i, k] = beta * (np.sqrt(v) - one)
    return arg, base


@numba.njit(cache=True, nogil=True)
def spread(base, ker, a_re, a_im, size):
    """Grid sums b[base_i + k] += ker[i, k] a_i (float32 products, float64 sums in echo order)."""
    b_re = np.zeros(size)
    b_im = np.zeros(size)
    for i in range(base.shape[0]):
        ar, ai, b = a_re[i], a_im[i], base[i]
        for k in range(ker.shape[1]):
            w = ker[i, k]
            b_re[b + k] += np.float64(w * ar)
            b_im[b + k] += np.float64(w * ai)
    return b_re, b_im


_TWO_PI = 2.0 * math.pi
_TWO_PI_HI = float(np.float32(_TWO_PI))  # 24 significant bits: q * hi is exact for q < 2 ** 29
_TWO_PI_LO = _TWO_PI - _TWO_PI_HI  # exact, 29 bits: q * lo is exact for q < 2 ** 24


@numba.njit(cache=True, nogil=True)
def _mod_2pi(a: float) -> float:
    """``remainder(a, 2 pi)``, with the truncated remainder computed exactly without ``fmod`` for
    |a| < 2 ** 24 turns: q = trunc(a / 2 pi) (corrected by one if the division rounded across an
    integer), then (|a| - q hi) - q lo, each step exact (the products fit 53 bits, the first
    difference by Sterbenz's lemma, the second because the remainder is representable)."""
    b = _TWO_PI
    if -b < a < b:
        r = a
    else:
        x = abs(a)
        q = np.floor(x / b)  # a float (math.floor would be an int64, overflowing)
        if not q < 16777216.0:
            r = np.fmod(a, b)
        else:
            r = (x - q * _TWO_PI_HI) - q * _TWO_PI_LO
            if r < 0.0:
                q -= 1.0
                r = (x - q * _TWO_PI_HI) - q * _TWO_PI_LO
            elif r >= b:
                q += 1.0
                r = (x - q * _TWO_PI_HI) - q * _TWO_PI_LO
            if a < 0.0:
                r = -r
    if r != 0.0:
        if r < 0.0:
            r += b
    else:
        r = 0.0
    return r


@numba.njit(cache=True, nogil=True)
def ramp_echoes(beam, range_m, radial, power, phase, mode, c_range, range_offset_m, c_doppler, c_half, k_phase,
                half_fs, scale, m_grid, row, offsets, u_scale, beta, f_all, arg, base, ph32, amp32, i_at, m_at):
    """One ramp's echoes as :meth:`.spectra.Synthesizer.spectra` and ``signal`` prepare them, in
    one pass: beat frequency f (``mode`` 0 single ramp f_r + 2 f_d, 1 up f_r + f_d, 2 down
    f_r - f_d) and phase (range phase -+ the half-ramp motion), then for the echoes with
    |f| < fs/2 the exponents of the kernel at their grid points (:func:`kernel_arguments`),
    their first grid index, the phase mod 2 pi and the amplitude sqrt(2 P) in float32.
    Written into f_all from ``i_at`` (every echo) and into arg, base, ph32, amp32 from ``m_at`` (those
    in the band; the echoes may come in parts, one call each); returns where the next part's go."""
    n, width = beam.shape[0], offsets.shape[0]
    one = np.float32(1.0)
    zero = np.float32(0.0)
    m = m_at
    for i in range(n):
        f_r = c_range * (range_m[i] - range_offset_m)
        f_d = c_doppler * radial[i]
        if mode == 0:
            f = f_r + 2.0 * f_d
        elif mode == 1:
            f = f_r + f_d
        else:
            f = f_r - f_d
        f_all[i_at + i] = f
        if not abs(f) < half_fs:
            continue
        if mode == 0:
            ph = phase[i] + k_phase * range_m[i]
        elif mode == 1:
            ph = phase[i] + k_phase * (range_m[i] - c_half * radial[i])
        else:
            ph = phase[i] + k_phase * (range_m[i] + c_half * radial[i])
        x = remainder(f * scale, m_grid)
        i0 = math.floor(x)
        frac = np.float32(x - i0)
        base[m] = np.intp(beam[i]) * row + np.intp(i0)
        amp32[m] = np.float32(np.sqrt(2.0 * power[i]))
        ph32[m] = np.float32(_mod_2pi(ph))
        for k in range(width):
            u = (offsets[k] - frac) * u_scale
            arg[m, k] = beta * (np.sqrt(max(one - u * u, zero)) - one)  # u is finite: max is np.maximum
        m += 1
    return m


@numba.njit(cache=True, nogil=True)
def spread_fold(base, ker, amp32, cos32, sin32, n_beams, m_grid, o):
    """:func:`spread` with a_re, a_im = amp32 cos, amp32 sin (float32), onto one padded row per
    beam, then the complex grid b + 1j b_im (numpy's arithmetic) with the wrapped columns folded
    (padded column c is grid point (c - o) mod M), as :meth:`.spectra.Synthesizer.signal` does."""
    width = ker.shape[1]
    row = m_grid + width - 1
    g = np.zeros(2 * n_beams * row)  # re, im interleaved: the same sums, closer in memory
    for i in range(base.shape[0]):
        ar, ai, b = amp32[i] * cos32[i], amp32[i] * sin32[i], 2 * base[i]
        for k in range(width):
            w = ker[i, k]
            g[b + 2 * k] += np.float64(w * ar)
            g[b + 2 * k + 1] += np.float64(w * ai)
    out = np.empty((n_beams, m_grid), np.complex128)
    for r in range(n_beams):
        p0 = 2 * r * row
        for c in range(m_grid):
            q = p0 + 2 * (o + c)
            out[r, c] = _b(g[q], g[q + 1])
        for c in range(o):  # b[:, M - o:] += padded[:, :o]
            q = p0 + 2 * c
            out[r, m_grid - o + c] += _b(g[q], g[q + 1])
        for c in range(width - 1 - o):  # b[:, :width - 1 - o] += padded[:, o + M:]
            q = p0 + 2 * (o + m_grid + c)
            out[r, c] += _b(g[q], g[q + 1])
    return out


@numba.njit(cache=True, nogil=True)
def _b(re, im):
    """numpy's ``re + 1j * im`` (1j * im as a complex product)."""
    return complex(re + (0.0 * im - 0.0), 0.0 + (0.0 + im))


@numba.njit(cache=True, nogil=True)
def windowed_samples(z, time_index, deapodize, noise, window):
    """(Re(z[:, time_index] * deapodize) + noise) * window: the real beat samples of a ramp
    (numpy's complex-times-real arithmetic), its thermal noise (or none if ``noise`` is empty)
    and the window."""
    nb, ns = z.shape[0], time_index.shape[0]
    out = np.empty((nb, ns))
    has_noise = noise.shape[0] > 0
    for r in range(nb):
        for k in range(ns):
            v = z[r, time_index[k]]
            s = v.real * deapodize[k] - v.imag * 0.0
            if has_noise:
                s = s + noise[r, k]
            out[r, k] = s * window[k]
    return out


@numba.njit(cache=True, nogil=True)
def bin_powers(x, n_bins, scale, skirts):
    """0.5 |x scale|^2 (numpy's complex-times-real) of the first ``n_bins`` bins, in float32, plus
    the float32 ``skirts`` (none if empty)."""
    nb = x.shape[0]
    out = np.empty((nb, n_bins), np.float32)
    has = skirts.shape[0] > 0
    for r in range(nb):
        for k in range(n_bins):
            v = x[r, k]
            re = v.real * scale - v.imag * 0.0
            im = v.real * 0.0 + v.imag * scale
            p = np.float32(0.5 * (re * re + im * im))
            if has:
                p = p + skirts[r, k]
            out[r, k] = p
    return out


@numba.njit(cache=True, nogil=True)
def skirt_select(power_w, range_m, l_ref, two_pi_f_ref, enbw, ramp_s, level):
    """Indices of :func:`.receiver.skirt_echoes`: ``np.nonzero(P l_ref (two_pi_f_ref tau)^2 enbw / ramp_s
    >= level)``, tau = 2 R / c, with numpy's operations in its order (``x ** 2`` is ``x * x``)."""
    n = power_w.shape[0]
    out = np.empty(n, np.intp)
    m = 0
    for i in range(n):
        tau = 2.0 * range_m[i] / 299_792_458.0
        q = two_pi_f_ref * tau
        flat = power_w[i] * l_ref * (q * q)
        if flat * enbw / ramp_s >= level:
            out[m] = i
            m += 1
    return out[:m].copy()
