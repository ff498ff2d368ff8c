"""The paper's closed forms for a sphere on a half-space, sections 4 and 5.

One function per equation (group), named by its number. Where the printed
equation differs from what follows from its neighbours, both exist: the
``_as_printed`` variant reproduces the paper, the plain name is the
consistent one, and ``docs/errata.md`` measures the difference.

Symbols (SI): m [kg] effective mass, V [m/s] normal impact speed, R [m]
effective radius, E [Pa] = E', E_loss [Pa] = E'', tan_delta = tg(beta),
k_p [-] correlation coefficient, omega [rad/s] = omega_x, tau1, tau2, tau
[s], x_m [m]. Functions broadcast over numpy arrays.
"""

from __future__ import annotations

import math

import numpy as np

#: Dimensionless Hertz contact duration tau V / x_max = 2 int_0^1 du /
#: sqrt(1 - u^(5/2)) = (4/5) B(2/5, 1/2) = 2.94328 (Landau & Lifshitz).
HERTZ_TAU_FACTOR = 0.8 * math.gamma(0.4) * math.gamma(0.5) / math.gamma(0.9)


# ---------------------------------------------------------------- Hertz ----
def hertz_x_max(m, V, E, R, k_p=1.0):
    """Elastic maximum approach (Landau): x_m = [15 m V^2 / (16 k_p E sqrt(R))]^(2/5),
    i.e. (65) with k_x = 1."""
    return (15.0 * m * V**2 / (16.0 * k_p * E * np.sqrt(R))) ** 0.4


def hertz_tau(m, V, E, R, k_p=1.0):
    """Elastic contact duration tau = 2.94328 x_m / V (Hertz/Landau)."""
    return HERTZ_TAU_FACTOR * hertz_x_max(m, V, E, R, k_p) / V


def hertz_F_max(m, V, E, R, k_p=1.0):
    """Elastic peak force (4/3) k_p E sqrt(R) x_m^(3/2) (30)."""
    return 4.0 / 3.0 * k_p * E * np.sqrt(R) * hertz_x_max(m, V, E, R, k_p) ** 1.5


# ------------------------------------------------ (53)-(58) normal works ----
def work_elastic_compression_53(x_m, E, R, k_p):
    """(53): A_xcm = 8/15 k_p E' sqrt(R) x_m^(5/2) [J]."""
    return 8.0 / 15.0 * k_p * E * np.sqrt(R) * x_m**2.5


def work_viscous_compression_54(x_m, E_loss, R, k_p, omega, tau1):
    """(54): A_xbm = 8 k_p E'' sqrt(R) x_m^(5/2) / (5 omega tau1) [J]."""
    return 8.0 * k_p * E_loss * np.sqrt(R) * x_m**2.5 / (5.0 * omega * tau1)


def work_elastic_restitution_55_as_printed(x_m, E_loss, R, k_p):
    """(55) as printed: 8/15 k_p E'' sqrt(R) x_m^(5/2) (E'' where E' is meant)."""
    return 8.0 / 15.0 * k_p * E_loss * np.sqrt(R) * x_m**2.5


def work_elastic_restitution_55(x_m, E, R, k_p):
    """(55) consistent: A_xct = A_xcm = 8/15 k_p E' sqrt(R) x_m^(5/2) [J]."""
    return work_elastic_compression_53(x_m, E, R, k_p)


def work_viscous_restitution_56(x_m, E_loss, R, k_p, omega, tau2):
    """(56): A_xbt = 8 k_p E'' sqrt(R) x_m^(5/2) / (5 omega tau2) [J]."""
    return 8.0 * k_p * E_loss * np.sqrt(R) * x_m**2.5 / (5.0 * omega * tau2)


def works_57(x_m, E, E_loss, R, k_p, omega, tau1, tau2):
    """(57): (A_xm, A_xt) = 8/15 k_p sqrt(R) x_m^(5/2) (E' +- 3 E''/(omega tau_{1,2})) [J]."""
    c = 8.0 / 15.0 * k_p * np.sqrt(R) * x_m**2.5
    return c * (E + 3 * E_loss / (omega * tau1)), c * (E - 3 * E_loss / (omega * tau2))


def works_58_as_printed(x_m, E_loss, tan_delta, R, k_p, omega, tau1, tau2):
    """(58) as printed: prefactor with E'' (should be E')."""
    c = 8.0 / 15.0 * k_p * E_loss * np.sqrt(R) * x_m**2.5
    return c * (1 + 3 * tan_delta / (omega * tau1)), c * (1 - 3 * tan_delta / (omega * tau2))


def works_58(x_m, E, tan_delta, R, k_p, omega, tau1, tau2):
    """(58) consistent: 8/15 k_p E' sqrt(R) x_m^(5/2) (1 +- 3 tg(beta)/(omega tau_{1,2})) [J]."""
    c = 8.0 / 15.0 * k_p * E * np.sqrt(R) * x_m**2.5
    return c * (1 + 3 * tan_delta / (omega * tau1)), c * (1 - 3 * tan_delta / (omega * tau2))


# ------------------------------------------ (59)-(65) compression, COR ----
def x_max_59_as_printed(m, V, E_loss, tan_delta, R, k_p, omega, tau1):
    """(59) as printed, with E'' (inherited from (58))."""
    wt = omega * tau1
    return (15.0 * m * wt * V**2 / (16.0 * (3 * tan_delta + wt) * k_p * E_loss * np.sqrt(R))) ** 0.4


def x_max_59(m, V, E, tan_delta, R, k_p, omega, tau1):
    """(59) consistent (E'): x_m from A_xm = m V^2/2 [m]."""
    wt = omega * tau1
    return (15.0 * m * wt * V**2 / (16.0 * (3 * tan_delta + wt) * k_p * E * np.sqrt(R))) ** 0.4


def energetic_cor_60(tan_delta, omega, tau1, tau2):
    """(60): e_x = k_x^2 = (omega tau2 - 3 tg)/(omega tau1 + 3 tg) * tau1/tau2."""
    return (omega * tau2 - 3 * tan_delta) / (omega * tau1 + 3 * tan_delta) * tau1 / tau2


def cor_62(tau1, tau2):
    """(62): k_x = tau1/tau2 (from the approximation (61))."""
    return tau1 / tau2


def tan_delta_63(cor, omega, tau1):
    """(63): tg(beta) = omega tau1 / 3 * (1 - k_x)/k_x."""
    return omega * tau1 / 3.0 * (1 - cor) / cor


def cor_64(tan_delta, omega, tau1):
    """(64): k_x = omega tau1 / (3 tg(beta) + omega tau1)."""
    return omega * tau1 / (3 * tan_delta + omega * tau1)


def x_max_65(m, V, E, R, k_p, cor):
    """(65): x_m = [15 m V^2 k_x / (16 k_p E' sqrt(R))]^(2/5) [m]."""
    return (15.0 * m * V**2 * cor / (16.0 * k_p * E * np.sqrt(R))) ** 0.4


# --------------------------------------------- (75)-(81) rolling shear ----
def P_m_76(x_m, R, k_p, D1):
    """(76): P_m = D1 x_m + 2 k_p sqrt(R x_m) [m] (sphere on a half-space, k_h = D1 (47*))."""
    return D1 * x_m + 2.0 * k_p * np.sqrt(R * x_m)


def shear_works_75(G, G_loss, omega_y, P_m, y1, yt, tau1, tau):
    """(75): (A_ybm, A_ycm, A_ybt, A_yct) [J]."""
    A_ybm = G_loss / (2 * omega_y) * P_m * y1**2 / tau1
    A_ycm = G / 2 * P_m * y1**2
    A_ybt = G_loss / (2 * omega_y) * P_m * (yt**2 - y1**2) / (tau - tau1)
    A_yct = G / 2 * P_m * (yt**2 - y1**2)
    return A_ybm, A_ycm, A_ybt, A_yct


def rebound_spin_79(G, P_m, J, yt):
    """(79): omega_t = sqrt(G' P_m / J_z) y_t [rad/s]."""
    return np.sqrt(G * P_m / J) * yt


def shear_dissipation_80(G_loss, omega_y, P_m, y1, yt, tau1, tau2):
    """(80): Q_omega = G''/(2 omega_y) P_m (y1^2/tau1 - y1^2/tau2 + yt^2/tau2) [J]."""
    return G_loss / (2 * omega_y) * P_m * (y1**2 / tau1 - y1**2 / tau2 + yt**2 / tau2)


def shear_dissipation_81(G_loss, omega_y, P_m, y1, yt, tau2, cor):
    """(81): (80) with tau1 = k_x tau2: G''/(2 omega_y tau2 k_x) P_m [y1^2 (1-k_x) + k_x yt^2] [J]."""
    return G_loss / (2 * omega_y * tau2 * cor) * P_m * (y1**2 * (1 - cor) + cor * yt**2)


# ----------------------------------------- (84)-(87) equivalent oscillator --
def equivalent_parameters_84(x_m, E, E_loss, G, G_loss, R, k_p, omega_x, omega_y, P_m):
    """(84): B_x [N s/m], C_x [N/m], B_y [N s/m], C_y [N/m]."""
    B_x = 16.0 * E_loss * k_p * np.sqrt(R) / (5.0 * omega_x) * np.sqrt(x_m)
    C_x = 16.0 / 15.0 * k_p * E * np.sqrt(R) * np.sqrt(x_m)
    return B_x, C_x, G_loss / omega_y * P_m, G * P_m


def omega_equivalent(stiffness_per_mass, tan_delta_eff):
    """Damped frequency of the equivalent oscillator with B = 3 tg C / omega (for x)
    or B = tg C / omega (for y): omega^2 = w0^2/2 (1 + sqrt(1 - q^2)), q = 3 tg (x)
    or tg (y) (section 8, after (99)). Raises where no real root exists."""
    q = np.asarray(tan_delta_eff, dtype=float)
    if np.any(q > 1.0):
        raise ValueError(
            f"no damped oscillation: q = {float(np.max(q)):.4g} > 1 (for the normal direction "
            "this is tg(beta) > 1/3, the bound (100))"
        )
    return np.sqrt(stiffness_per_mass / 2.0 * (1.0 + np.sqrt(1.0 - q**2)))


def omega_x_equivalent(m, x_m, E, tan_delta, R, k_p):
    """omega_x of (86) with (84): omega^4 - w0^2 omega^2 + w0^4 tg^2 = 0 (section 8) [rad/s]."""
    C_x = 16.0 / 15.0 * k_p * E * np.sqrt(R) * np.sqrt(x_m)
    return omega_equivalent(C_x / m, 3.0 * np.asarray(tan_delta))


def omega_y_equivalent(m, P_m, G, tan_delta_G):
    """omega_y of (84)/(86): omega_y^2 = C_y/m - (B_y/2m)^2, B_y = G'' P_m/omega_y [rad/s]."""
    return omega_equivalent(G * P_m / m, np.asarray(tan_delta_G))


def damped_oscillation_86(t, v0, omega, delta):
    """(86): x = v0/omega e^(-delta t) sin(omega t) [m]."""
    return v0 / omega * np.exp(-delta * t) * np.sin(omega * t)


def damped_velocity_92(t, v0, omega, delta):
    """(92): x' = v0/omega e^(-delta t) [omega cos(omega t) - delta sin(omega t)] [m/s]."""
    return v0 / omega * np.exp(-delta * t) * (omega * np.cos(omega * t) - delta * np.sin(omega * t))


def tau_87(omega):
    """(87): tau_x = T_x/2 = pi/omega_x [s]."""
    return math.pi / np.asarray(omega)


# -------------------------------------------------- (88)-(90) MSF COR ----
def tan_delta_88(cor):
    """(88): tg(beta) = pi/3 (1 - k_x)/(1 + k_x)."""
    return math.pi / 3.0 * (1 - np.asarray(cor)) / (1 + np.asarray(cor))


def cor_89(tan_delta):
    """(89): k_x = (pi - 3 tg(beta))/(pi + 3 tg(beta))."""
    t = np.asarray(tan_delta)
    return (math.pi - 3 * t) / (math.pi + 3 * t)


def x_max_90(m, V, E, tan_delta, R, k_p):
    """(90): x_m = [15 m V^2/(16 k_p E' sqrt(R)) (pi - 3 tg)/(pi + 3 tg)]^(2/5) [m]."""
    return x_max_65(m, V, E, R, k_p, cor_89(tan_delta))


# ---------------------------------------------- (93)-(95) duration ----
def tau_93(cor, delta):
    """(93): tau_x = -ln(k_x)/delta_x [s]."""
    return -np.log(cor) / delta


def delta_94(m, x_m, E, tan_delta, R, k_p, tau):
    """(94): delta_x = B_x/2m = 8 k_p E' tg tau sqrt(R x_m)/(5 pi m) [1/s]."""
    return 8.0 * k_p * E * tan_delta * tau * np.sqrt(R) * np.sqrt(x_m) / (5.0 * math.pi * m)


def _tau_shape(cor, V):
    k = np.asarray(cor, dtype=float)
    return -(1 + k) * np.log(k) / (V**0.4 * (1 - k) * k**0.2)


#: Constant of (95) as printed, 2 (5/8)^(4/5), and the one that follows from
#: (65), (88), (93), (94), (15/8)(16/15)^(1/5).
C95_PRINTED = 2.0 * (5.0 / 8.0) ** 0.8
C95_CONSISTENT = 15.0 / 8.0 * (16.0 / 15.0) ** 0.2


def tau_95_as_printed(m, V, E, R, k_p, cor):
    """(95) as printed: tau^2 = -2 (1+k) ln k / (V^(2/5) (1-k) k^(1/5)) (5m/(8 k_p E' sqrt R))^(4/5) [s]."""
    return np.sqrt(C95_PRINTED * _tau_shape(cor, V) * (m / (k_p * E * np.sqrt(R))) ** 0.8)


def tau_95(m, V, E, R, k_p, cor):
    """(95) as it follows from (65), (88), (93), (94): constant (15/8)(16/15)^(1/5) [s]."""
    return np.sqrt(C95_CONSISTENT * _tau_shape(cor, V) * (m / (k_p * E * np.sqrt(R))) ** 0.8)


# ------------------------------------------ (96)-(99) identification ----
def E_storage_96(m, V, R, k_p, tau, cor):
    """(96) as printed (the inverse of (95) as printed): E' [Pa]."""
    k = np.asarray(cor, dtype=float)
    return 5.0 * m / (8.0 * k_p * V**0.5 * np.sqrt(R) * tau**2.5) * (
        (-2.0 * np.log(k)) * (1 + k) / (k**0.2 * (1 - k))
    ) ** 1.25


def E_loss_97_as_printed(m, V, R, k_p, tau, cor):
    """(97) as printed: 15 pi m/(24 k_p V^(1/2) sqrt(R) tau^(5/2)) (-2 ln k)^(5/4) ((1+k)/(k(1-k)))^(1/4) [Pa].
    Equals 3 tg(beta)(88) E'(96): three times (48)."""
    k = np.asarray(cor, dtype=float)
    return 15.0 * math.pi * m / (24.0 * k_p * V**0.5 * np.sqrt(R) * tau**2.5) * (
        -2.0 * np.log(k)
    ) ** 1.25 * ((1 + k) / (k * (1 - k))) ** 0.25


def E_loss_97(m, V, R, k_p, tau, cor):
    """(97) consistent with (48): E'' = tg(beta)(88) E'(96) [Pa]."""
    return tan_delta_88(cor) * E_storage_96(m, V, R, k_p, tau, cor)


def brilliantov_A_98(E_loss, E_young, nu, k_p, omega):
    """(98): A = E'' k_p (1 - nu^2)/(Y omega_x) [s]."""
    return E_loss * k_p * (1 - nu**2) / (E_young * omega)


def brilliantov_A_99(tan_delta, nu, k_p, tau):
    """(99): A = k_p tg(beta)/pi (1 - nu^2) tau_x [s]."""
    return k_p * tan_delta / math.pi * (1 - nu**2) * tau


def brilliantov_A_98_corrected(E_loss, E_young, nu, k_p, omega):
    """(98) with Brilliantov et al.'s (1996) dissipative force Y sqrt(R) A sqrt(xi) xi'/(1 - nu^2)
    (coefficient 1, where the paper's (4*) prints 4): A = 4 E'' k_p (1 - nu^2)/(Y omega_x) [s]."""
    return 4.0 * brilliantov_A_98(E_loss, E_young, nu, k_p, omega)


def kuwabara_kono_A_equivalent(tan_delta, omega):
    """A [s] for which the Kuwabara-Kono force rho sqrt(x)(x + 3/2 A x') with
    rho = 4/3 k_p E' sqrt(R) (the same E' and k_p) equals the MSF normal force (47):
    3/2 A rho = 4 k_p E'' sqrt(R)/omega_x, so A = 2 tg(beta)/omega_x, independent of k_p."""
    return 2.0 * np.asarray(tan_delta) / np.asarray(omega)


def paper_kp(x_m, R):
    """k_p at the maximum approach, (15), for the closed forms in ``msf`` mode."""
    return np.sqrt(2.0 - np.asarray(x_m) / R)


def kp_for_mode(mode: str, m, V, E, tan_delta, R, iterations: int = 30):
    """k_p used by the closed forms: 1 (hertz), sqrt(2) (msf-small), or
    sqrt(2 - x_m/R) with x_m from (90) by fixed-point iteration (msf)."""
    if mode == "hertz":
        return 1.0
    if mode == "msf-small":
        return math.sqrt(2.0)
    k = math.sqrt(2.0)
    for _ in range(iterations):
        x_m = x_max_90(m, V, E, tan_delta, R, k)
        if x_m >= 2 * R:
            raise ValueError(f"x_max = {x_m:.4g} m >= 2R = {2 * R:.4g} m: outside the msf k_p of (15)")
        k = math.sqrt(2.0 - x_m / R)
    return k
