"""Finite Fourier series of a joint position (Swevers et al. 1997): the excitation's trajectory family.

    q(t)   = q0 + sum_k a_k / (w k) sin(w k t) - b_k / (w k) cos(w k t)
    qd(t)  = sum_k a_k cos(w k t) + b_k sin(w k t)
    qdd(t) = sum_k b_k w k cos(w k t) - a_k w k sin(w k t)

``w = 2 pi / T``; periodic by construction; ``q0 = sum_k b_k / (w k)`` makes ``q(0) = 0``.
Angles in rad, times in s.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class Fourier:
    """One joint's periodic position reference (rad); ``a``, ``b``: velocity amplitudes (rad/s)."""

    period: float
    a: np.ndarray
    b: np.ndarray

    @property
    def coefficients(self) -> np.ndarray:
        return np.r_[self.a, self.b]

    @property
    def offset(self) -> float:
        """``q0`` (rad): what makes ``q(0) = 0``."""
        return float(np.sum(self.b / frequencies(self.period, self.a.size)))

    def evaluate(self, t) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``q`` (rad), ``qd`` (rad/s), ``qdd`` (rad/s^2) at the times ``t`` (s)."""
        x = self.coefficients
        return tuple(P @ x for P in basis(self.period, self.a.size, t))


def frequencies(period: float, harmonics: int) -> np.ndarray:
    return 2 * np.pi / period * np.arange(1, harmonics + 1)


def basis(period: float, harmonics: int, t) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Matrices taking the coefficients ``[a, b]`` to ``q``, ``qd``, ``qdd`` at ``t`` (``q0`` included)."""
    w = frequencies(period, harmonics)
    wt = np.outer(np.asarray(t, dtype=float), w)
    s, c = np.sin(wt), np.cos(wt)
    return np.c_[s / w, (1 - c) / w], np.c_[c, s], np.c_[-s * w, c * w]
