"""The deterministic emission sequence of a seed (:class:`Emitter`): when,
which size class, how fast, in which direction and from where on the exit
disk each particle leaves the nozzle."""

from __future__ import annotations

import bisect
import math
from dataclasses import dataclass

import numpy as np

from .spec import SPEED_TRUNCATION_SD, JetSpec


@dataclass(slots=True)
class _Emission:
    """One particle leaving the nozzle: time [s], class, start [m] and
    velocity [m/s] (3-tuples of floats)."""

    t: float
    cls: int
    p: tuple[float, float, float]
    v: tuple[float, float, float]
    waited: bool = False
    blocked: bool = False


class Emitter:
    """The deterministic sequence of emissions of a seed: arrival times
    (uniform or Poisson at the feed rate), size class, speed (truncated
    normal), direction (uniform in solid angle in the cone), start point
    (uniform over the exit disk). Independent of the engine, so both engines
    see the same particles for the same seed.

    Per emission the draws are, in this order: an exponential gap (Poisson
    arrivals only), one uniform for the class (more than one class; the
    inverse of the classes' cumulative probabilities, as
    ``Generator.choice`` with ``p``), standard normals until one lies within
    SPEED_TRUNCATION_SD (speed_sd > 0), and four uniforms (cone angle and
    azimuth, exit radius and azimuth). Scalar draws and float arithmetic."""

    def __init__(self, spec: JetSpec, seed):
        self.spec = spec
        seq = seed if isinstance(seed, np.random.SeedSequence) else np.random.SeedSequence(seed)
        self.rng = np.random.default_rng(seq)
        self.e1, self.e2 = spec.nozzle.basis()
        self.count = 0
        self._t = 0.0
        self._offset = 0.0
        sp, nz = spec.particles, spec.nozzle
        cdf = np.asarray(sp.probabilities, dtype=float).cumsum()
        cdf /= cdf[-1]
        self._cdf = cdf.tolist()
        self._axis = tuple(nz.direction)
        self._b1, self._b2 = tuple(self.e1.tolist()), tuple(self.e2.tolist())
        self._cos_half = math.cos(math.radians(nz.half_angle))
        self._r_exit = 0.5 * nz.diameter
        self._exit = tuple(nz.position)

    def shift(self, delay: float) -> None:
        """Delay every later emission by ``delay`` [s]."""
        self._offset += float(delay)

    def next(self) -> _Emission:
        sp, rng = self.spec.particles, self.rng
        if sp.arrival == "uniform":
            t = (self.count + 0.5) / sp.feed_rate + self._offset
        else:
            self._t += rng.exponential(1.0 / sp.feed_rate)
            t = self._t + self._offset
        cls = bisect.bisect_right(self._cdf, rng.random()) if len(self._cdf) > 1 else 0
        v = sp.speed_mean
        if sp.speed_sd > 0:
            while True:
                z = rng.standard_normal()
                if abs(z) <= SPEED_TRUNCATION_SD:
                    break
            v = sp.speed_mean + z * sp.speed_sd
        u1, u2, u3, u4 = rng.random(4).tolist()  # the same stream as four scalar draws
        cos_a = 1.0 - u1 * (1.0 - self._cos_half)
        sin_a = math.sqrt(max(0.0, 1.0 - cos_a * cos_a))
        phi = 2.0 * math.pi * u2
        r = self._r_exit * math.sqrt(u3)
        psi = 2.0 * math.pi * u4
        cp, sp_, cq, sq = math.cos(phi), math.sin(phi), math.cos(psi), math.sin(psi)
        (a0, a1, a2), (b0, b1, b2), (c0, c1, c2), (x0, x1, x2) = self._axis, self._b1, self._b2, self._exit
        self.count += 1
        return _Emission(t, cls, (x0 + r * (cq * b0 + sq * c0), x1 + r * (cq * b1 + sq * c1), x2 + r * (cq * b2 + sq * c2)),
                         (v * (cos_a * a0 + sin_a * (cp * b0 + sp_ * c0)), v * (cos_a * a1 + sin_a * (cp * b1 + sp_ * c1)),
                          v * (cos_a * a2 + sin_a * (cp * b2 + sp_ * c2))))
