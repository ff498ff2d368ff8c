"""Temperature in the exact viscoelastic impact (msf_contact.viscoelastic).

Time-temperature superposition: at temperature T every relaxation time is
a_T tau_i (WLF, the convention of ``Material.at``: E(omega, T) =
E_ref(omega a_T)). The hereditary equation of motion m d'' = -F[d] is then
invariant under t -> a_T t if the speed scales by 1/a_T and the mass by
a_T^2 (d_T(t) = d_ref(t / a_T), the same force values): so the impact at T
is the reference-temperature impact of mass m / a_T^2 at speed a_T v with
its contact time multiplied by a_T, and the same COR, x_max and F_max.
"""

import math

from msf_contact import WLF, Body, Material, PronySeries
from msf_contact.viscoelastic import Relaxation, exact_normal_impact, viscoelastic_impact

#: Both sides are integrations at the solver's RTOL (1e-11) of the same
#: equation in scaled time; COR, x_max and F_max converge to ~1e-9, so 1e-7.
SHIFT_RTOL = 1e-7
R, RHO, NU, V = 0.02, 1100.0, 0.45, 1.0
#: An SLS whose loss peak (omega tau_1 ~ 1 at ~1e3 rad/s) lies near the
#: impact's frequency, so the shift changes the COR by far more than SHIFT_RTOL.
PRONY = PronySeries(E_inf=2e7, E_i=(3e7,), tau_i=(1e-3,))
WLF_NR = WLF(C1=8.86, C2=101.6, T_ref=293.15)  #: WLF's "universal" constants with T_s (Williams et al. 1955)


def test_temperature_shift_is_a_time_scaling_of_the_reference_impact():
    E0, tan0 = PRONY.moduli(1e3)
    ball = Material("sls", E0, tan0, NU, RHO, master_curve=PRONY, wlf=WLF_NR)
    sphere = Body.sphere(ball, R)
    T = 303.15
    a_T = 10.0 ** WLF_NR.log10_aT(T)
    assert a_T < 0.5  # warmer: relaxes faster (the test would not see a sign error at a_T ~ 1)

    hot = viscoelastic_impact(sphere, Body.half_space(Material.rigid_body()), V, temperature=T)
    ref = exact_normal_impact(Relaxation.from_prony(PRONY), NU, R, sphere.mass / a_T**2, V * a_T)
    assert abs(hot.cor_n / ref.cor - 1) < SHIFT_RTOL
    assert abs(hot.tau / (a_T * ref.tau) - 1) < SHIFT_RTOL
    assert abs(hot.x_max / ref.x_max - 1) < SHIFT_RTOL
    assert abs(hot.F_max / ref.F_max - 1) < SHIFT_RTOL

    # and the shift matters: the reference-temperature impact at the same mass and speed differs
    cold = exact_normal_impact(Relaxation.from_prony(PRONY), NU, R, sphere.mass, V)
    assert abs(cold.cor - hot.cor_n) > 1e3 * SHIFT_RTOL


def test_material_at_temperature_and_shifted_relaxation_agree():
    """The solver's shift and the master curve's (Material.at) are one convention."""
    ball = Material("sls", *PRONY.moduli(1e3)[:1], 0.5, NU, RHO, master_curve=PRONY, wlf=WLF_NR)
    T = 283.15
    a_T = 10.0 ** WLF_NR.log10_aT(T)
    rel = Relaxation.from_prony(PRONY).shifted(a_T)
    for omega in (1e1, 1e3, 1e5):
        at = ball.at(omega, T)
        s, l_ = rel.moduli(omega)
        assert math.isclose(at.E_storage, s, rel_tol=1e-12)
        assert math.isclose(at.tan_delta, l_ / s, rel_tol=1e-12)
