"""The gaps the manager keeps between steps, and the check that they still
agree with the engine's geometry (issue 10: "never a silent wrong answer").

KEPT_GAP_DOC is the physics; :class:`KeptGapCheck` the never-silent check.
"""

from __future__ import annotations

import warnings

import numpy as np

from msf_contact._validate import ValidityWarning

from .state import V_ONSET_MIN, elastic_energy

KEPT_GAP_DOC = """The kept gap and the engine's half-step lead (issue 10).

A pair not in contact that was a candidate in the last step starts its step
from the manager's own gap x_m (ContactManager._own_gaps), not from the
engine's x_e: the engines' semi-implicit Euler moves a body by dt v_end, so
over a step in which the approach rate changed by dx' the engine's x_e
advances (dt/2) dx' more than the integrated x (state.RELAX_DOC, "the
lead"). Over free flight and over a sub-cycled step with its timing
correction (engines._contacts: the engine's step then moves the body by the
integrated displacement plus (dt/2) dx'), e = x_e - x_m changes by exactly
(dt/2) dx', so

    c = x_e - (dt/2) x'_0 - x_m        (x'_0: the approach rate at the step
                                        start, the timing correction taken out)

stays constant: x~ = x_e - (dt/2) x'_0 is the engine's gap the manager's
integration follows (and the position at which the island energy check and
scripts/pile.py count the potential energy, z - (dt/2) v). The kept gap is
relaxed by settle_rate a step toward x_e itself, whose lead (dt/2) x'_0
comes and goes with the pair's own motion: a row that bounces or chatters
is kept only in the steps it is open, where x'_0 has one sign, so each step
pulls x_m the same way and c ratchets. Measured, a steel sphere (R = 10 mm)
bouncing on a steel floor at 14 mm/s in MuJoCo at dt = 1 ms (a 3-step
cycle): its engine position sank 0.075 um a bounce below the manager's
bounce point, which paid the bounce's viscous loss (COR 0.9964) out of the
potential energy, so the bounce kept its 14.0 mm/s for 30 bounces (the
energy check saw E fall, no gain); |c| 0.2 um median, 0.9 um largest
(tests/test_chatter.py's sphere). Relaxed toward x~ instead (tried, not
landed: docs/engines.md), the bounce decays at its records' COR and |c| is
3e-10 m, but a box's corner, a link's point and two spheres' turning normal
do not keep c (their lead is not (dt/2) dx'), and relaxing only the
sphere-on-plane rows so gained 3.1e-4 J in an island of the 2-sphere pile
(a frame mixed in one island).

Which rows the check watches: a free sphere on a fixed body (the pairs the
adapters mark ``own_gap`` and ``settle_rigid``, both bodies' orientation
free, one of them fixed: ContactManager._shadow_rows), where the contact
point stays on the line of the centre and the normal is fixed, so x~ is
exact. A box's corner moves with the box's turn inside the step, a link's
point with its joints (limits, drives, pushes the free flight does not
see), two spheres' normal turns.

Never silent (:class:`KeptGapCheck`, on the same rows; a contact the others
leave found deep is flagged by the adapters' balance.DeepOnsets): a kept gap
open (x_m < 0) while the
engine has the bodies inside each other beyond their lead, x~ > 0, is a body
pressed into another with no force on it; the bound o of the fall-back
grows with every step of a chattering row (by (dt/2)|dx'| a step), so such a
state can last. The traced case (docs/engines.md): a steel sphere 91 um into
a steel wall while the kept gap read 28 um open, which then left at
0.22 m/s. It is flagged when the elastic energy of x~, int_0^x~ F_n(x', 0)
dx' (what a contact found there would store, never worked for), exceeds
KEPT_GAP_ENERGY_RATIO of the pair's approach energy 1/2 m v_n^2 (at least
1/2 m V_ONSET_MIN^2)."""

#: A kept gap is flagged when the elastic energy of the overlap the engine holds with no force on it,
#: int_0^x~ F_n(x', 0) dx', exceeds this many times the pair's approach energy 1/2 m max(x'_0, V_ONSET_MIN)^2
#: (a contact found there would hold ten times what the pair brings). Not the deep-onset bound
#: (ENERGY_GAIN_RTOL, 1e-3): the kept gap's relaxation toward the engine's x leaves the bouncing steel
#: sphere of tests/test_chatter.py up to 0.6 um inside beyond its lead (the ratchet, KEPT_GAP_DOC), up to
#: 1.34 times its approach energy (pybullet; MuJoCo 0.04-0.3 um); the traced ejection held 41 um, ~400 times.
KEPT_GAP_ENERGY_RATIO = 10.0
#: A flagged pair is warned again on stderr only for an overlap this many times the largest warned for it
#: (each flagged step is listed in ContactManager.kept_gap_flags and noted on the pair's next record).
REWARN_FACTOR = 10.0


class KeptGapCheck:
    """KEPT_GAP_DOC's never-silent check, per step, on the rows that kept the
    manager's gap. ``flags``: (t [s], pair, x~ [m], x_m [m], E_el(x~) [J],
    approach energy [J]) of every flagged row-step."""

    def __init__(self, P: int):
        self.flags: list[tuple[float, int, float, float, float, float]] = []
        self._warned = np.zeros(P)  # the largest x~ warned per pair [m] (0: none)

    def check(self, mgr, pair, kept, xt, xm, xd0, n, W) -> None:
        """pair (k,), kept (k,) bool (the rows that kept the manager's gap),
        xt (k,) the engine's x less its half-step lead [m], xm (k,) the
        manager's gap the step started from before the relaxation [m], xd0
        (k,) the approach rate at the step start [m/s], n (k, 3), W (k, 3, 3)."""
        bad = np.flatnonzero(kept & (xt > 0.0))
        if bad.size == 0:
            return
        pp = pair[bad]
        nWn = np.einsum("ki,kij,kj->k", n[bad], W[bad], n[bad])
        m = 1.0 / np.where(nWn > 0.0, nWn, np.inf)
        v = np.maximum(np.abs(xd0[bad]), V_ONSET_MIN)
        approach = 0.5 * m * v**2
        E = np.zeros(bad.size)
        for r in range(bad.size):  # rare rows: the law's constants for a contact beginning now (its onset)
            law = mgr.pairs[int(pp[r])].law
            with np.errstate(all="ignore"):
                E[r] = elastic_energy(law, xt[bad[r]:bad[r] + 1], law.onset(v[r:r + 1], m[r:r + 1]))[0]
        for r in np.flatnonzero(~(E <= KEPT_GAP_ENERGY_RATIO * approach)).tolist():  # (NaN flagged)
            p, i = int(pp[r]), int(bad[r])
            x_t, x_m = float(xt[i]), float(xm[i])
            self.flags.append((mgr._t_now, p, x_t, x_m, float(E[r]), float(approach[r])))
            note = (f"kept gap left behind by the engine (dt = {mgr.dt:g} s): at t = {mgr._t_now:.6g} s the engine "
                    f"had the bodies {x_t:.3g} m inside each other beyond their half-step lead while the manager "
                    f"integrated a gap of {-x_m:.3g} m, with no force on that overlap (its elastic energy "
                    f"{E[r]:.3g} J, {E[r] / approach[r]:.3g} of the approach energy): the kept gap drifted from the "
                    "engine's geometry over steps the pair's contacts chattered or the body's other contacts' "
                    "timing corrections moved it (engines._contacts.gaps.KEPT_GAP_DOC); take a smaller dt, or "
                    "give the pair a Coulomb friction (mu) if its tangential spring throws the body back")
            mgr.note_next_contact(p, note)
            if x_t > REWARN_FACTOR * self._warned[p]:
                again = "" if self._warned[p] == 0.0 else f" (again: {self._warned[p]:.3g} m warned before)"
                self._warned[p] = x_t
                warnings.warn(f"pair {p} ({mgr.pair_names[p][0]}, {mgr.pair_names[p][1]}): {note}{again}; warned "
                              f"again only for an overlap {REWARN_FACTOR:g} times larger; every step is listed in "
                              "ContactManager.kept_gap_flags and noted on the pair's next record",
                              ValidityWarning, stacklevel=4)

