"""The engine-agnostic core (engines._contacts, engines._geometry) driven by a
tiny pure-numpy engine and checked against the reference solver.

The fake engine integrates free spheres with semi-implicit Euler, as
MuJoCo's Euler integrator and pybullet do (v += dt a; p += dt v), and
applies the manager's step-averaged force equal and opposite at the contact
point. Everything the adapters add (reading the engine, Jacobians) is absent
here, so these tests measure the core alone.
"""

from __future__ import annotations

import math
from functools import lru_cache

import numpy as np
import pytest
from scipy.integrate import quad
from scipy.optimize import brentq

from engines._contacts import ContactManager, closing_distance, effective_inverse_inertia_free
from engines._geometry import check_pair_supported, sphere_box_face, sphere_plane, sphere_sphere
from engines.base import ContactKinematics, PairSpec
from msf_contact import Body, ContactPair, Curvature, Material, make_law, preset, simulate_impact
from msf_contact.laws import MSFLaw

# -- tolerances -------------------------------------------------------------
#: Issue 3 acceptance at >= 50 engine steps per contact: COR 0.1 %, tau 1 %.
COR_RTOL_RESOLVED = 1e-3
TAU_RTOL_RESOLVED = 1e-2
#: Issue 3 acceptance at >= 250 steps per contact: 0.02 % (COR and tau).
RTOL_FINE = 2e-4
#: Issue 3 acceptance at robotics steps (1-2 ms, contact 0.3-0.7 ms): 0.5 %.
COR_RTOL_ROBOTICS = 5e-3
#: The core alone: RK4 with >= 200 substeps per duration and exact onset and
#: separation times measures <= 1e-5 (MSF's F ~ t^(1/2) at onset limits it);
#: 1e-4 catches a regression long before the acceptance bound.
CORE_RTOL = 1e-4
#: Oblique impacts: cor_t and spin within 2 % (issue 3); the engine's lever
#: arm is frozen over a step (|r| = R - x/2 at the step start), the
#: reference's varies with x: an O(x/R) ~ 1e-3 difference.
OBLIQUE_RTOL = 2e-2
#: Resting ball: static overlap within 2 % (issue 3).
REST_RTOL = 2e-2
#: Momentum of two free spheres: 1e-9 relative (issue 3); the fake engine
#: adds +F and -F, so only round-off remains (~1e-16 per step).
MOMENTUM_RTOL = 1e-9

G = 9.81
RIGID = Material.rigid_body()


# -- the fake engine ----------------------------------------------------------
class FakeEngine:
    """Free solid spheres (bodies 0..B-1) and an optional fixed plane z = 0.

    pairs: list of (i, j) with j = -1 for the plane; sphere i is body 1.
    Semi-implicit Euler: v += dt (g + F/m), w += dt I^-1 tau, p += dt v.
    """

    def __init__(self, specs, pairs, radius, mass, pos, vel, omega, dt, gravity=0.0):
        self.R = np.asarray(radius, float)
        self.m = np.asarray(mass, float)
        self.I = 0.4 * self.m * self.R**2
        self.p = np.array(pos, float)
        self.v = np.array(vel, float)
        self.w = np.array(omega, float)
        self.idx = np.array(pairs, int)
        self.dt = dt
        self.g = np.array([0.0, 0.0, -gravity])
        self.t = 0.0
        self.mgr = ContactManager(specs, dt, "fake")
        self.mgr.set_body_probe(lambda q: {"omega1": self.w[self.idx[q, 0]].copy()})

    def kinematics(self):
        i, j = self.idx[:, 0], self.idx[:, 1]
        plane = j < 0
        det_x = np.empty(len(i))
        nrm, pt, pt1, pt2 = (np.empty((len(i), 3)) for _ in range(4))
        if np.any(plane):
            d = sphere_plane(self.p[i[plane]], self.R[i[plane]], np.zeros(3), np.array([0.0, 0.0, 1.0]))
            det_x[plane], nrm[plane], pt[plane], pt1[plane], pt2[plane] = d.x, d.normal, d.point, d.point1, d.point2
        if np.any(~plane):
            d = sphere_sphere(self.p[i[~plane]], self.R[i[~plane]], self.p[j[~plane]], self.R[j[~plane]])
            det_x[~plane], nrm[~plane], pt[~plane], pt1[~plane], pt2[~plane] = (
                d.x, d.normal, d.point, d.point1, d.point2)
        self._pt1, self._pt2 = pt1, pt2  # each body's force acts at its own contact point
        r1 = pt1 - self.p[i]
        v1 = self.v[i] + np.cross(self.w[i], r1)
        W = np.empty((len(i), 3, 3))
        Wc = np.empty((len(i), 3, 3))
        v_rel, vc_rel, a = v1.copy(), self.v[i].copy(), np.repeat(self.g[None], len(i), 0)
        for q in range(len(i)):
            I1 = self.I[i[q]] * np.eye(3)
            if plane[q]:
                W[q] = effective_inverse_inertia_free(self.m[i[q]], I1, r1[q], math.inf, None, np.zeros(3))
                Wc[q] = np.eye(3) / self.m[i[q]]
            else:
                r2 = pt2[q] - self.p[j[q]]
                W[q] = effective_inverse_inertia_free(self.m[i[q]], I1, r1[q], self.m[j[q]],
                                                      self.I[j[q]] * np.eye(3), r2)
                Wc[q] = np.eye(3) * (1 / self.m[i[q]] + 1 / self.m[j[q]])
                v_rel[q] -= self.v[j[q]] + np.cross(self.w[j[q]], r2)
                vc_rel[q] -= self.v[j[q]]
                a[q] = 0.0
        xd = -np.einsum("ij,ij->i", v_rel, nrm)
        cand = det_x > -closing_distance(xd, -np.einsum("ij,ij->i", a, nrm), self.dt)
        cand[self.mgr.required_pairs] = True
        c = np.flatnonzero(cand)
        return ContactKinematics(pair=c, x=det_x[c], normal=nrm[c], point=pt[c], v_rel=v_rel[c],
                                 v_com_rel=vc_rel[c], W=W[c], W_com=Wc[c], a_ext=a[c], t=self.t)

    def step(self):
        self.integrate(self.mgr.step(self.kinematics()))

    def integrate(self, out):
        """Apply the manager's forces (ContactForces) over one step and advance."""
        acc = np.repeat(self.g[None], len(self.m), 0)
        alpha = np.zeros_like(self.w)
        for q, F in zip(out.pair, out.force):
            i, j = self.idx[q]
            acc[i] += F / self.m[i]
            alpha[i] += np.cross(self._pt1[q] - self.p[i], F) / self.I[i]
            if j >= 0:
                acc[j] -= F / self.m[j]
                alpha[j] -= np.cross(self._pt2[q] - self.p[j], F) / self.I[j]
        self.v += self.dt * acc
        self.w += self.dt * alpha
        self.p += self.dt * self.v
        self.t += self.dt

    def run_until_records(self, n_records, t_max):
        while len(self.mgr.records) < n_records or self.mgr.active_count or self.mgr.pending_count:
            if self.t > t_max:
                raise AssertionError(f"only {len(self.mgr.records)} impacts by t = {self.t}")
            self.step()
        return self.mgr.pop_records()


def balls_on_plate(law, R, speed, dt, gaps, angle_deg=90.0, gravity=0.0, spin=0.0, tangential="contact-point"):
    """One ball per gap [m] (distance between the surfaces at t = 0), all on the plate."""
    mat = law.pair.body1
    m = 4.0 / 3.0 * math.pi * R**3 * mat.density
    n = len(gaps)
    a = math.radians(angle_deg)
    vt = speed * math.cos(a) if angle_deg < 90 else 0.0
    vn = speed * math.sin(a)
    pos = [[0.1 * k, 0.0, R + g] for k, g in enumerate(gaps)]
    vel = [[vt, 0.0, -vn]] * n
    om = [[0.0, spin, 0.0]] * n
    specs = [PairSpec(f"ball{k}", "plate", law, tangential) for k in range(n)]
    return FakeEngine(specs, [(k, -1) for k in range(n)], [R] * n, [m] * n, pos, vel, om, dt, gravity)


def sphere_on_plate_ref(law, R, speed, angle=90.0, spin=0.0):
    return simulate_impact(law, Body.sphere(law.pair.body1, R), Body.half_space(RIGID), speed, angle, spin)


def rel(got, want):
    return abs(got / want - 1.0)


# -- materials and laws -------------------------------------------------------
RUBBER = preset("natural-rubber")
PTFE = preset("ptfe")
R_RUBBER, V_RUBBER = 0.02, 2.0  # contact ~2.4 ms
R_PTFE, V_PTFE = 0.012, 1.0  # contact 0.35-0.45 ms


def laws_for(mat, R):
    pair = ContactPair(mat, RIGID)
    c = Curvature.sphere_on_plane(R)
    return {
        "msf": make_law("msf", pair, c, omega=8000.0 if mat is PTFE else 3000.0),
        "hertz": make_law("hertz", pair, c),
        "kuwabara-kono": make_law("kuwabara-kono", pair, c, A=1e-6 if mat is PTFE else 2e-5),
        "hunt-crossley": make_law("hunt-crossley", pair, c, cor=0.7),
        "spring-dashpot": make_law("spring-dashpot", pair, c),
    }


LAWS_RUBBER = laws_for(RUBBER, R_RUBBER)
LAWS_PTFE = laws_for(PTFE, R_PTFE)


@lru_cache(maxsize=None)
def ref_rubber(name):
    return sphere_on_plate_ref(LAWS_RUBBER[name], R_RUBBER, V_RUBBER)


@lru_cache(maxsize=None)
def ref_ptfe(name):
    return sphere_on_plate_ref(LAWS_PTFE[name], R_PTFE, V_PTFE)


# -- resolved steps -----------------------------------------------------------
@pytest.mark.parametrize("name", list(LAWS_RUBBER))
@pytest.mark.parametrize("steps_per_contact, cor_rtol, tau_rtol",
                         [(50, COR_RTOL_RESOLVED, TAU_RTOL_RESOLVED), (250, RTOL_FINE, RTOL_FINE)])
def test_resolved_steps_match_reference(name, steps_per_contact, cor_rtol, tau_rtol):
    ref = ref_rubber(name)
    dt = ref.tau / steps_per_contact
    eng = balls_on_plate(LAWS_RUBBER[name], R_RUBBER, V_RUBBER, dt, [0.3 * V_RUBBER * dt])
    (rec,) = eng.run_until_records(1, 0.05)
    assert rel(rec.cor_n, ref.cor_n) < cor_rtol
    assert rel(rec.tau, ref.tau) < tau_rtol
    # the engine's own velocity after the contact agrees with the record (the step-averaged force is right)
    eng.step()
    eng.step()  # the timing correction of the last contact step is removed one step later
    assert rel(eng.v[0, 2], ref.cor_n * V_RUBBER) < cor_rtol
    assert rel(rec.x_max, ref.x_max) < CORE_RTOL
    assert rel(rec.F_max, ref.F_max) < CORE_RTOL
    assert rel(rec.tau1, ref.tau1) < CORE_RTOL
    ke_in = 0.5 * ref.inputs["mass_reduced"] * V_RUBBER**2  # energies relative to the impact energy
    assert abs(rec.W_diss_n - ref.W_diss_n) < CORE_RTOL * ke_in
    assert abs(rec.W_el_comp - ref.W_el_comp) < CORE_RTOL * ke_in
    assert abs(rec.W_visc_rest - ref.W_visc_rest) < CORE_RTOL * ke_in
    assert rec.engine == "fake" and rec.dt == dt and rec.parameters == ref.parameters


# -- robotics steps: 20 onset phases at once ------------------------------------
N_PHASES = 20


@pytest.mark.parametrize("name", list(LAWS_PTFE))
@pytest.mark.parametrize("dt", [1e-3, 2e-3])
def test_robotics_steps_every_phase(name, dt):
    ref = ref_ptfe(name)
    assert 0.3e-3 <= ref.tau <= 0.7e-3  # the contact is shorter than one step
    gaps = V_PTFE * dt * (np.arange(N_PHASES) + 0.5) / N_PHASES  # onset anywhere in the step
    eng = balls_on_plate(LAWS_PTFE[name], R_PTFE, V_PTFE, dt, gaps)
    recs = eng.run_until_records(N_PHASES, 0.05)
    assert len(recs) == N_PHASES
    cor = np.array([r.cor_n for r in recs])
    tau = np.array([r.tau for r in recs])
    assert np.max(np.abs(cor / ref.cor_n - 1)) < COR_RTOL_ROBOTICS
    assert np.max(np.abs(cor / ref.cor_n - 1)) < CORE_RTOL
    assert np.max(np.abs(tau / ref.tau - 1)) < CORE_RTOL
    # the engine's bodies leave with the recorded speed (two steps: the timing correction is removed)
    eng.step()
    eng.step()
    assert np.max(np.abs(eng.v[:, 2] / (ref.cor_n * V_PTFE) - 1)) < CORE_RTOL


def test_robotics_steps_self_consistent_msf():
    """Default MSF (omega_x self-consistent) at 2 ms, a few phases (its onset solve is slow)."""
    law = make_law("msf", ContactPair(PTFE, RIGID), Curvature.sphere_on_plane(R_PTFE))
    ref = sphere_on_plate_ref(law, R_PTFE, V_PTFE)
    dt = 2e-3
    gaps = V_PTFE * dt * np.array([0.05, 0.5, 0.95])
    recs = balls_on_plate(law, R_PTFE, V_PTFE, dt, gaps).run_until_records(3, 0.05)
    for r in recs:
        assert rel(r.cor_n, ref.cor_n) < CORE_RTOL
        assert rel(r.tau, ref.tau) < CORE_RTOL
        assert rel(r.omega_x, ref.omega_x) < 1e-9  # same onset speed and mass: the same law constants


def test_contact_spanning_steps_and_overlap_zero():
    """A contact spanning ~3 steps, with the overlap-zero separation rule (tensile force allowed)."""
    law = make_law("msf", ContactPair(RUBBER, RIGID), Curvature.sphere_on_plane(R_RUBBER), omega=3000.0,
                   separation="overlap-zero")
    ref = sphere_on_plate_ref(law, R_RUBBER, V_RUBBER)
    dt = ref.tau / 2.7
    gaps = V_RUBBER * dt * np.array([0.1, 0.6])
    recs = balls_on_plate(law, R_RUBBER, V_RUBBER, dt, gaps).run_until_records(2, 0.05)
    for r in recs:
        assert r.ended_by == "overlap-zero" == ref.ended_by
        assert rel(r.cor_n, ref.cor_n) < CORE_RTOL
        assert rel(r.tau, ref.tau) < CORE_RTOL


# -- oblique impacts with spin --------------------------------------------------
@pytest.mark.parametrize("angle", [30.0, 60.0])
@pytest.mark.parametrize("dt", [None, 1e-3])
def test_oblique_impact_cor_t_and_spin(angle, dt):
    law = LAWS_PTFE["msf"]
    ref = sphere_on_plate_ref(law, R_PTFE, V_PTFE, angle)
    dt = dt or ref.tau / 50
    vn = V_PTFE * math.sin(math.radians(angle))
    eng = balls_on_plate(law, R_PTFE, V_PTFE, dt, [0.4 * vn * dt], angle_deg=angle)
    (rec,) = eng.run_until_records(1, 0.05)
    assert rel(rec.cor_n, ref.cor_n) < CORE_RTOL
    assert rel(rec.cor_t, ref.cor_t) < OBLIQUE_RTOL
    assert rel(rec.cor_t_contact, ref.cor_t_contact) < OBLIQUE_RTOL
    assert rel(rec.spin_out, ref.spin_out) < OBLIQUE_RTOL
    assert rec.spin_in == 0.0
    assert rel(rec.W_diss_t, ref.W_diss_t) < OBLIQUE_RTOL


# -- a ball comes to rest -------------------------------------------------------
def test_dropped_ball_comes_to_rest_at_static_overlap_without_energy_gain():
    lossy = Material("lossy-rubber", 5e6, 0.3, 0.49, 930.0)
    R = R_RUBBER
    law = make_law("msf", ContactPair(lossy, RIGID), Curvature.sphere_on_plane(R), omega=3000.0)
    m = 4.0 / 3.0 * math.pi * R**3 * lossy.density
    dt = 2e-3
    eng = balls_on_plate(law, R, 0.0, dt, [0.02], gravity=G)
    n_steps = int(0.8 / dt)
    energy = []
    for _ in range(n_steps):
        eng.step()
        energy.append(0.5 * m * eng.v[0, 2] ** 2 + m * G * (eng.p[0, 2] - R))
    recs = eng.mgr.pop_records()
    assert len(recs) >= 5
    # each bounce leaves with less energy than the one before (rebound speeds from the records)
    v_out = np.array([r.cor_n * r.inputs["v_n_in"] for r in recs])
    assert np.all(np.diff(v_out) < 0)
    assert all(r.cor_n < 1 and r.W_diss_n > 0 for r in recs)
    # at rest: the contact persists at the static overlap, internally and in the engine
    st = eng.mgr.state(0)
    assert st is not None and abs(st["xdot"]) < 1e-6
    o = {k: np.array([v]) for k, v in st["onset"].items()}
    x_s = brentq(lambda x: float(law.normal_force(np.array([x]), np.zeros(1), o)[0]) - m * G, 1e-9, R)
    assert rel(st["x"], x_s) < REST_RTOL
    assert rel(R - eng.p[0, 2], x_s) < REST_RTOL
    assert np.all(np.isfinite(energy))
    # total mechanical energy of the engine's ball never rises above the drop energy
    assert max(energy[5:]) <= m * G * 0.02 * (1 + 1e-3)


#: An elastic (Hertz) ball bouncing under gravity at dt = 1 ms keeps its landing
#: speed: with the timing correction the spread over 6 bounces measures 4e-5
#: (without it, 0.6-1.5 %: the engine's position after a step-averaged
#: impulse depends on where in the step the impact fell, and gravity turns
#: that into energy).
ELASTIC_BOUNCE_RTOL = 1e-3


def test_elastic_ball_keeps_its_bounce_speed():
    dt = 1e-3
    eng = balls_on_plate(LAWS_PTFE["hertz"], R_PTFE, 0.0, dt, [0.05, 0.0503, 0.0507], gravity=G)
    for _ in range(int(0.9 / dt)):
        eng.step()
    recs = eng.mgr.pop_records()
    for b in range(3):
        v_in = np.array([r.inputs["v_n_in"] for r in recs if r.inputs["pair"] == b])
        assert len(v_in) >= 4
        assert np.max(np.abs(v_in / v_in[0] - 1)) < ELASTIC_BOUNCE_RTOL
        assert all(abs(r.cor_n - 1) < CORE_RTOL for r in recs)


# -- two free spheres -----------------------------------------------------------
def test_two_free_spheres_conserve_momentum_and_match_reference():
    law = make_law("msf", ContactPair(PTFE, PTFE), Curvature.two_spheres(R_PTFE, R_PTFE), omega=8000.0)
    m = 4.0 / 3.0 * math.pi * R_PTFE**3 * PTFE.density
    speed, dt = 1.0, 1e-3
    pos = [[0.0, 0.0, 2 * R_PTFE + 0.37 * speed * dt], [0.0, 0.0, 0.0]]
    eng = FakeEngine([PairSpec("a", "b", law)], [(0, 1)], [R_PTFE] * 2, [m, m], pos,
                     [[0.0, 0.0, -0.5 * speed], [0.0, 0.0, 0.5 * speed]], np.zeros((2, 3)), dt)
    p0 = m * eng.v.sum(axis=0)
    (rec,) = eng.run_until_records(1, 0.05)
    eng.step()
    eng.step()
    p1 = m * eng.v.sum(axis=0)
    assert np.max(np.abs(p1 - p0)) <= MOMENTUM_RTOL * m * speed
    ref = simulate_impact(law, Body.sphere(PTFE, R_PTFE), Body.sphere(PTFE, R_PTFE), speed)
    assert rel(rec.cor_n, ref.cor_n) < CORE_RTOL
    assert rel(rec.tau, ref.tau) < CORE_RTOL
    assert rel(rec.inputs["mass_effective"], m / 2) < 1e-12


# -- fast path against the plain law ----------------------------------------------
class _PlainTangentialMSF(MSFLaw):
    """Same law; overriding tangential_force makes the manager call it instead of its inlined copy."""

    def tangential_force(self, x, s, sdot, onset, F_n=None):
        return super().tangential_force(x, s, sdot, onset, F_n)


def test_inlined_tangential_force_equals_the_laws():
    pair, c = ContactPair(PTFE, RIGID), Curvature.sphere_on_plane(R_PTFE)
    fast = make_law("msf", pair, c, omega=8000.0, mu=0.3)
    plain = _PlainTangentialMSF(pair, c, omega=8000.0, mu=0.3)
    out = []
    for law in (fast, plain):
        eng = balls_on_plate(law, R_PTFE, V_PTFE, 1e-3, [0.2e-3], angle_deg=30.0)
        (rec,) = eng.run_until_records(1, 0.05)
        out.append((rec.cor_t, rec.spin_out, rec.f_max))
    assert np.allclose(out[0], out[1], rtol=1e-12, atol=0)
    assert out[0][2] == pytest.approx(0.3, rel=1e-9)  # the Coulomb cap is reached at 30 degrees


# -- bad input and contract -------------------------------------------------------
def _spec():
    return PairSpec("ball", "plate", LAWS_PTFE["hertz"])


def test_bad_inputs_are_refused():
    with pytest.raises(ValueError, match="dt"):
        ContactManager([_spec()], 0.0, "fake")
    with pytest.raises(ValueError, match="pairs is empty"):
        ContactManager([], 1e-3, "fake")
    with pytest.raises(ValueError, match="tangential"):
        ContactManager([PairSpec("a", "b", LAWS_PTFE["hertz"], "sideways")], 1e-3, "fake")
    mgr = ContactManager([_spec()], 1e-3, "fake")
    kin = ContactKinematics(pair=np.array([3]), x=np.zeros(1), normal=np.array([[0, 0, 1.0]]),
                            point=np.zeros((1, 3)), v_rel=np.zeros((1, 3)), v_com_rel=np.zeros((1, 3)),
                            W=np.eye(3)[None], W_com=np.eye(3)[None], a_ext=np.zeros((1, 3)), t=0.0)
    with pytest.raises(ValueError, match="pair"):
        mgr.step(kin)
    with pytest.raises(ValueError, match="mass"):
        effective_inverse_inertia_free(0.0, np.eye(3), np.zeros(3), math.inf, None, np.zeros(3))
    with pytest.raises(ValueError, match=r"together has shape \(2,\); expected \(1,\)"):
        mgr.set_together(np.ones(2, bool))


def test_a_line_contact_refuses_a_shape_without_a_side():
    from engines._narrow import SideLine
    from msf_contact.shapes import Sphere

    with pytest.raises(ValueError, match="a line contact needs a capsule or a cylinder, not Sphere"):
        SideLine(Sphere(0.01), ("ball", "floor"))


def test_unlisted_contact_is_an_error_not_a_silent_cut():
    eng = balls_on_plate(LAWS_PTFE["hertz"], R_PTFE, V_PTFE, 1e-4, [0.0])
    eng.step()
    assert eng.mgr.active_count == 1
    kin = eng.kinematics()
    empty = ContactKinematics(pair=kin.pair[:0], x=kin.x[:0], normal=kin.normal[:0], point=kin.point[:0],
                              v_rel=kin.v_rel[:0], v_com_rel=kin.v_com_rel[:0], W=kin.W[:0],
                              W_com=kin.W_com[:0], a_ext=kin.a_ext[:0], t=kin.t)
    with pytest.raises(ValueError, match="required_pairs"):
        eng.mgr.step(empty)


def test_effective_inverse_inertia_of_a_sphere():
    """Sphere on a plane, r = -R n: W = 1/m (I + 5/2 (I - n n^T)) (tangential 7/(2m), normal 1/m)."""
    m, R = 2.0, 0.1
    n = np.array([0.0, 0.0, 1.0])
    W = effective_inverse_inertia_free(m, 0.4 * m * R**2 * np.eye(3), -R * n, math.inf, None, np.zeros(3))
    assert np.allclose(W, (np.eye(3) + 2.5 * (np.eye(3) - np.outer(n, n))) / m, rtol=1e-14)
    W2 = effective_inverse_inertia_free(m, 0.4 * m * R**2 * np.eye(3), -R * n, m, 0.4 * m * R**2 * np.eye(3), R * n)
    assert np.allclose(W2, 2 * W, rtol=1e-14)


# -- geometry -------------------------------------------------------------------------
def test_sphere_plane_detection():
    d = sphere_plane([[1.0, 2.0, 0.09]], 0.1, [0.0, 0.0, 0.0], [0.0, 0.0, 2.0])
    assert d.x[0] == pytest.approx(0.01, rel=1e-12)
    assert np.allclose(d.normal[0], [0, 0, 1])
    assert np.allclose(d.point[0], [1.0, 2.0, -0.005])  # middle of the overlap
    assert np.allclose(d.point1, d.point) and np.allclose(d.point2, d.point)
    gap = sphere_plane([[0.0, 0.0, 0.13]], 0.1, [0.0, 0.0, 0.0], [0.0, 0.0, 1.0])
    assert gap.x[0] == pytest.approx(-0.03, rel=1e-12)
    assert np.allclose(gap.point1[0], [0, 0, 0.03]) and np.allclose(gap.point2[0], [0, 0, 0.0])
    c = d.curvature(0)
    assert (c.R1a, c.R1b) == (0.1, 0.1) and math.isinf(c.R2a)
    s = d.swapped()
    assert np.allclose(s.normal[0], [0, 0, -1]) and math.isinf(s.radii1[0, 0])


def test_sphere_sphere_detection():
    d = sphere_sphere([[0.0, 0.0, 0.25]], 0.1, [[0.0, 0.0, 0.0]], 0.2)
    assert d.x[0] == pytest.approx(0.05, rel=1e-12)
    assert np.allclose(d.normal[0], [0, 0, 1])
    assert np.allclose(d.point[0], [0, 0, 0.175])
    with pytest.raises(ValueError, match="coincide"):
        sphere_sphere([[0.0, 0.0, 0.0]], 0.1, [[0.0, 0.0, 0.0]], 0.2)


def test_sphere_box_face_and_edge_refusal():
    rot = np.array([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])  # box turned 90 deg about z
    half = [0.2, 0.1, 0.05]
    # above the top face, inside its rectangle
    d = sphere_box_face([[0.05, 0.1, 0.14]], 0.1, [0, 0, 0], rot, half)
    assert d.x[0] == pytest.approx(0.01, rel=1e-9)
    assert np.allclose(d.normal[0], [0, 0, 1])
    # beside the face that is the box's local +y axis, now world -x
    d = sphere_box_face([[-0.19, 0.0, 0.0]], 0.1, [0, 0, 0], rot, half)
    assert np.allclose(d.normal[0], [-1, 0, 0]) and d.x[0] == pytest.approx(0.01, rel=1e-9)
    # over an edge: refused
    with pytest.raises(ValueError, match="edge/corner is not smooth"):
        sphere_box_face([[0.15, 0.0, 0.1]], 0.1, [0, 0, 0], rot, half)
    with pytest.raises(ValueError, match="corner"):
        sphere_box_face([[0.15, 0.25, 0.1]], 0.1, [0, 0, 0], rot, half)
    # far from the box with a margin: not checked
    d = sphere_box_face([[1.0, 1.0, 1.0]], 0.1, [0, 0, 0], rot, half, margin=0.01)
    assert d.x[0] < -0.01


@pytest.mark.parametrize("shapes", [("capsule", "plane"), ("box", "box"), ("mesh", "sphere"),
                                    ("cylinder", "plane"), ("plane", "plane")])
def test_unsupported_pairs_are_refused(shapes):
    with pytest.raises(ValueError, match=f"{shapes[0]!r}, {shapes[1]!r}"):
        check_pair_supported(*shapes)


def test_supported_pairs():
    assert check_pair_supported("Sphere", "plane") == "sphere-plane"
    assert check_pair_supported("box", "sphere") == "sphere-box"
    assert check_pair_supported("sphere", "sphere") == "sphere-sphere"


# -- the settled path ---------------------------------------------------------------
STEEL = preset("steel")
#: A resting contact on the settled path holds the static overlap to the
#: Newton tolerance (SETTLED_VTOL: the internal x within ~1e-12, the engine's
#: within ~3e-7 relative) once the engine's offset from the first, sub-cycled
#: step (13 % here) has relaxed at settle_rate = 10 %/step (150 steps:
#: 0.9^150 x 13 % ~ 2e-8); 1e-6 is far inside REST_RTOL.
SETTLED_REST_RTOL = 1e-6
#: The energy of a kicked resting ball may not rise between steps by more than
#: this share of the kick's energy (round-off of m g z ~ 1e-18 J against ~2e-12 J).
ENERGY_ROUNDOFF = 1e-3


def _static_overlap(law, m, onset):
    o = {k: np.atleast_1d(np.asarray(v, float))[:1] for k, v in onset.items()}
    return brentq(lambda x: float(law.normal_force(np.array([x]), np.zeros(1), o)[0]) - m * G, 1e-15, 1e-2,
                  xtol=1e-22, rtol=1e-15)


def test_resting_steel_on_steel_at_2ms_is_stable_at_the_static_overlap():
    """Steel on steel at dt = 2 ms: the contact's own frequency omega = sqrt(K/m)
    is ~30/dt, so an explicit force would blow up (explicit schemes need omega dt
    < 2) and sub-cycling costs ~1,600 RK4 substeps per step. On the settled
    path the ball rests at m g = F_n(x_s, 0), and a kick (below the settled
    criterion) dies out without any energy gain."""
    R, dt = 0.01, 2e-3
    law = make_law("msf", ContactPair(STEEL, STEEL), Curvature.sphere_on_plane(R))
    m = 4.0 / 3.0 * math.pi * R**3 * STEEL.density
    x_s = _static_overlap(law, m, law.onset([1.0], [m]))
    omega = math.sqrt(1.5 * m * G / x_s / m)  # dF/dx = 3/2 F/x at the static overlap
    assert omega * dt > 20
    eng = balls_on_plate(law, R, 0.0, dt, [-0.99 * x_s], gravity=G)  # at rest, 1 % above the static overlap

    def energy():
        """Kinetic + gravity + elastic energy of the contact int_0^x F_n(x', 0) dx' [J]."""
        o = {k: np.array([v]) for k, v in eng.mgr.state(0)["onset"].items()}
        x = R - eng.p[0, 2]
        u = quad(lambda q: float(law.normal_force(np.array([q]), np.zeros(1), o)[0]), 0.0, x, epsabs=0, epsrel=1e-13)[0]
        return 0.5 * m * eng.v[0] @ eng.v[0] + 0.5 * eng.I[0] * eng.w[0] @ eng.w[0] + m * G * eng.p[0, 2] + u

    for _ in range(150):
        eng.step()
    assert eng.mgr.settled[0] and eng.mgr.active[0]
    x_s = _static_overlap(law, m, eng.mgr.state(0)["onset"])
    assert rel(eng.mgr.state(0)["x"], x_s) < SETTLED_REST_RTOL
    assert rel(R - eng.p[0, 2], x_s) < SETTLED_REST_RTOL
    # a kick into the plate and along it, below the settled criterion: stays settled, no energy gain
    kick = np.array([1e-6, 0.0, -1e-5])
    eng.v[0] += kick
    e_kick = 0.5 * m * kick @ kick
    e = [energy()]
    for _ in range(200):
        eng.step()
        assert eng.mgr.settled[0]
        e.append(energy())
    assert np.all(np.isfinite(e)) and np.all(np.isfinite(eng.p)) and np.all(np.isfinite(eng.v))
    # backward Euler of gravity and the contact together: the energy only falls (to round-off of m g z)
    assert np.all(np.diff(e) <= ENERGY_ROUNDOFF * e_kick)
    assert rel(R - eng.p[0, 2], x_s) < SETTLED_REST_RTOL
    # normal motion gone; the sideways kick ends as rolling without slip at 5/7 of it (solid sphere)
    assert abs(eng.v[0, 2]) < 1e-3 * abs(kick[2])
    assert rel(eng.v[0, 0], 5.0 / 7.0 * kick[0]) < 1e-3
    assert abs(eng.v[0, 0] - eng.w[0, 1] * R) < 1e-3 * kick[0]


def test_settled_rest_equals_sub_cycled_rest():
    """The same drop with the settled path on and off (every contact
    sub-cycled): the same bounces, the same rest at the static overlap."""
    lossy = Material("lossy-rubber", 5e6, 0.3, 0.49, 930.0)
    R, dt = R_RUBBER, 2e-3
    law = make_law("msf", ContactPair(lossy, RIGID), Curvature.sphere_on_plane(R), omega=3000.0)
    m = 4.0 / 3.0 * math.pi * R**3 * lossy.density
    out = {}
    for settled in (True, False):
        eng = balls_on_plate(law, R, 0.0, dt, [0.02], gravity=G)
        eng.mgr.settled_path = settled
        n_settled = 0
        for _ in range(int(0.8 / dt)):
            eng.step()
            n_settled += int(eng.mgr.settled[0])
        st = eng.mgr.state(0)
        out[settled] = (st["x"], R - eng.p[0, 2], [r.cor_n for r in eng.mgr.pop_records()],
                        _static_overlap(law, m, st["onset"]), n_settled)
    assert out[True][4] > 50 and out[False][4] == 0  # the settled path was taken, and only when allowed
    for settled in (True, False):
        x_int, x_eng, _, x_s, _ = out[settled]
        assert rel(x_int, x_s) < REST_RTOL and rel(x_eng, x_s) < REST_RTOL
    assert rel(out[True][0], out[False][0]) < 1e-5
    assert rel(out[True][1], out[False][1]) < 1e-5
    assert len(out[True][2]) == len(out[False][2]) >= 5
    assert np.allclose(out[True][2], out[False][2], rtol=1e-9, atol=0)


def test_struck_settled_ball_returns_to_sub_cycling():
    """A steel ball rests on a soft pad (settled); a small steel ball falls on
    it. The pad contact leaves the settled path at the strike, and the
    steel-steel impact's COR matches the reference solver's for two free
    spheres: the pad's own period (~35 ms) is ~1000 times the strike's, so the
    resting ball is free for the strike."""
    pad = Material("pad", 1e6, 0.3, 0.45, 1000.0)
    RA, RB, dt = 0.02, 0.005, 1e-3
    law_pad = make_law("msf", ContactPair(STEEL, pad), Curvature.sphere_on_plane(RA), omega=300.0)
    law_hit = make_law("msf", ContactPair(STEEL, STEEL), Curvature.two_spheres(RB, RA))
    mA, mB = (4.0 / 3.0 * math.pi * r**3 * STEEL.density for r in (RA, RB))
    x_s = _static_overlap(law_pad, mA, law_pad.onset([math.sqrt(2 * G * 1e-4)], [mA]))
    t_hit, v0 = 0.15, 0.5  # B reaches A after t_hit, falling from v0
    gap = v0 * t_hit + 0.5 * G * t_hit**2
    pos = [[0.0, 0.0, RA - x_s], [0.0, 0.0, 2 * RA - x_s + RB + gap]]
    eng = FakeEngine([PairSpec("A", "pad", law_pad), PairSpec("B", "A", law_hit)], [(0, -1), (1, 0)], [RA, RB],
                     [mA, mB], pos, [[0.0, 0.0, 0.0], [0.0, 0.0, -v0]], np.zeros((2, 3)), dt, gravity=G)
    settled_before = False
    while not (eng.mgr.active[1] or eng.mgr.pending_count or eng.mgr.records):  # the strike lasts ~50 us
        settled_before = bool(eng.mgr.settled[0])
        eng.step()
        assert eng.t < 2 * t_hit
    assert settled_before  # the pad contact was on the settled path when B arrived
    eng.step()
    assert eng.mgr.active[0] and not eng.mgr.settled[0]  # the hit pushed the pad contact back to sub-cycling
    while eng.mgr.active[1] or not eng.mgr.records:
        eng.step()
    rec = next(r for r in eng.mgr.pop_records() if r.inputs["pair"] == 1)
    v_in = rec.inputs["v_n_in"]
    assert rel(v_in, v0 + G * t_hit) < 0.05
    ref = simulate_impact(law_hit, Body.sphere(STEEL, RB), Body.sphere(STEEL, RA), v_in)
    assert rel(rec.cor_n, ref.cor_n) < COR_RTOL_ROBOTICS
    for _ in range(50):  # the pad contact takes the strike, without NaN
        eng.step()
    assert np.all(np.isfinite(eng.p)) and np.all(np.isfinite(eng.v))
