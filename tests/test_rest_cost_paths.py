"""The cheaper resting step of robot models changes no result (issue 13, the
walkers' rest cost): MujocoAdapter poses a lying side's ends
(SideEndLaw.set_pose, their onset masses, the law refresh) only for the
line pairs with a candidate row in the step (_pose_lines), and
elastic_energy takes only the onset keys a law reads (state.TakenOnset).
Compared here bit for bit against every pair posed in every step, on a
gymnasium walker (its own XML, RK4, frame_skip) moving and then lying at
rest. Likewise the pairs read through Jacobians all at once
(MujocoAdapter._slow_rows: the narrow phase's contact list read as arrays,
the capsule sides' ends by side_ends_many, J, v_rel and a_ext of every pair
by stacked matmuls, the candidates' Jacobians kept for the coupling blocks)
against the pair-by-pair path (_slow_rows_each); and the lying sides' ends'
normal forces and elastic energies of every law group in one compiled call
(state.side_forces, side_energies: relax, ContactManager._resting) against
the laws' own numpy methods, group by group."""
import warnings

import numpy as np
import pytest

from engines._contacts.state import TakenOnset, elastic_energy
from msf_contact import ContactPair, Curvature, make_law, preset

gym = pytest.importorskip("gymnasium")  # gymnasium[mujoco] is in the test extra: never skipped in CI

TORQUE_STEPS, REST_STEPS = 30, 20  # env steps (x4 mj_steps): Walker2d falls within the torques and lies still


def _run(lazy: bool, batched: bool = True, name: str = "Walker2d-v5"):
    from engines.mujoco import MujocoAdapter, installed
    from scripts.gym_check import gym_msf

    env, model, data, pairs = gym_msf(name)
    rng = np.random.default_rng(5)
    traj = []
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        ad = MujocoAdapter(model, data, pairs)
        ad._lazy_pose = lazy
        ad._batched_rows = batched
        ad.manager._batched_laws = batched
        posed = []
        line_slots = ad._line_slots
        ad._line_slots = lambda k, n: posed.append(k) or line_slots(k, n)
        with installed(ad):
            for i in range(TORQUE_STEPS + REST_STEPS):
                a = rng.uniform(-1, 1, env.action_space.shape) if i < TORQUE_STEPS else np.zeros(env.action_space.shape)
                env.step(a)
                traj.append(np.concatenate([data.qpos, data.qvel]))
    env.close()
    return np.array(traj), [repr(r) for r in ad.records], len(posed), ad


def test_lazy_line_poses_change_no_bit():
    t_lazy, rec_lazy, n_lazy, ad = _run(True)
    t_all, rec_all, n_all, _ = _run(False)
    assert rec_lazy, "the walker's sides must have touched the floor"
    assert any(ad._line[k].mode == "line" for k in ad._line), "a side must lie on the floor at the end"
    np.testing.assert_array_equal(t_lazy, t_all)  # positions and velocities, every env step
    assert rec_lazy == rec_all
    assert n_lazy < n_all  # the lazy path left out the poses nothing read


def test_batched_rows_change_no_bit():
    t_new, rec_new, _, ad = _run(True, True, "Ant-v5")
    t_ref, rec_ref, _, _ = _run(True, False, "Ant-v5")
    assert rec_new, "the ant's sides must have touched the floor"
    assert any(ad._line[k].mode == "line" for k in ad._line), "a side must lie on the floor at the end"
    np.testing.assert_array_equal(t_new, t_ref)  # positions and velocities, every env step
    assert rec_new == rec_ref


def test_side_ends_many_is_side_ends():
    from scipy.spatial.transform import Rotation

    from engines._narrow import side_end_constants, side_ends, side_ends_many
    from msf_contact.shapes import Capsule, Cylinder

    rng = np.random.default_rng(3)
    k = 40
    shapes = [Capsule(rng.uniform(0.01, 0.1), rng.uniform(0.05, 0.3)) if i % 3 else
              Cylinder(rng.uniform(0.02, 0.1), rng.uniform(0.05, 0.2), edge_radius=1e-3) for i in range(k)]
    c = np.array([side_end_constants(q) for q in shapes])
    rot = Rotation.random(k, random_state=4).as_matrix()
    z = np.array([0.6, 0.8, 0.0])  # lying exactly flat on the plane z = 0 (cos tilt 1, rise +-0)
    rot[::4] = np.stack([np.cross(z, [0.0, 0.0, 1.0]), [0.0, 0.0, 1.0], z], axis=1)
    pos, plane = rng.standard_normal((k, 3)), rng.standard_normal((k, 3))
    normal = np.tile([0.0, 0.0, 1.0], (k, 1))
    normal[1::2] = Rotation.random(k // 2, random_state=5).as_matrix()[:, :, 2]
    many = side_ends_many(c[:, 0], c[:, 1], c[:, 2], pos, rot, plane, normal)
    for i in range(k):
        one = side_ends(shapes[i], pos[i], rot[i], plane[i], normal[i])
        for f in ("x", "lowest", "rise", "normal"):
            np.testing.assert_array_equal(getattr(many[i], f), getattr(one, f))
        assert many[i].tilt == one.tilt


def test_side_kernel_is_the_laws_numpy():
    """engines._kernel.side_normal_forces and side_elastic_energy give SideEndLaw's
    contact_normal_force (an array of approaches, and one alone: _width_one's sum) and
    elastic_energy bit for bit, flat and tilted either way, at and near x = 0; and the MSF
    point laws' (a sphere, an elliptic contact, overlap-zero separation)."""
    import math

    from engines import _kernel as K
    from engines._contacts.compiled import kernel_law
    from engines._contacts.state import _GL_S, _GL_S2, _GL_W
    from engines._narrow import SideEndLaw

    tmpl = make_law("msf", ContactPair(preset("natural-rubber"), preset("steel")), Curvature.sphere_on_plane(0.02))
    rng = np.random.default_rng(7)
    laws = []
    for i in range(12):
        r = rng.uniform(0.01, 0.05)
        law = (SideEndLaw(tmpl, r, 1e-3, rng.uniform(0.05, 0.4), True) if i % 3 == 0
               else SideEndLaw(tmpl, r, r, rng.uniform(0.05, 0.4), False))
        tilt = (0.0, 1e-4, 0.02, 0.1)[i % 4]
        law.set_pose(tilt, (0.0, math.sin(tilt), -math.sin(tilt), math.sin(tilt))[i % 4])
        laws.append(law)
    pair = ContactPair(preset("natural-rubber"), preset("steel"))
    points = [make_law("msf", pair, Curvature.sphere_on_plane(0.005)),
              make_law("msf", pair, Curvature(0.03, 0.01, math.inf, math.inf)),
              make_law("msf", pair, Curvature.sphere_on_plane(0.02), separation="overlap-zero")]
    laws += points
    LC = np.array([kernel_law(q)[1] for q in laws])
    k = 9
    for g, law in enumerate(laws):
        assert kernel_law(law)[0] == (K.CODE_MSF if any(law is q for q in points) else K.CODE_SIDE)
        x = np.concatenate([[0.0, 1e-9], rng.uniform(0.0, 3e-3, k - 2)])
        on = {"E": rng.uniform(1e6, 5e6, k), "eta_E": rng.uniform(1e2, 1e4, k)}
        oc = np.zeros((k, K.NOC))
        oc[:, 0], oc[:, 1] = on["E"], on["eta_E"]
        p, kg, out = np.arange(k), np.full(k, g), np.empty(k)
        K.side_normal_forces(LC, kg, oc, p, x, np.zeros(k, bool), out)
        np.testing.assert_array_equal(out, law.contact_normal_force(x, np.zeros(k), on))
        K.side_normal_forces(LC, kg, oc, p, x, np.ones(k, bool), out)
        alone = [law.contact_normal_force(x[i:i + 1], np.zeros(1), {q: v[i:i + 1] for q, v in on.items()})[0]
                 for i in range(k)]
        np.testing.assert_array_equal(out, alone)
        K.side_elastic_energy(LC, kg, oc, p, x, _GL_S2, _GL_S, _GL_W, np.empty(8), out)
        np.testing.assert_array_equal(out, elastic_energy(law, x, on))


def test_taken_onset_takes_only_what_the_law_reads():
    law = make_law("msf", ContactPair(preset("natural-rubber"), preset("steel")), Curvature.sphere_on_plane(0.02))
    k = 5
    rng = np.random.default_rng(0)
    onset = {"E": rng.uniform(1e6, 2e6, k), "eta_E": rng.uniform(1e2, 1e3, k), "G": rng.uniform(1e5, 1e6, k),
             "eta_Gy": np.ones(k), "eta_Gz": np.ones(k), "omega_x": np.ones(k)}
    taken = []
    o = TakenOnset(onset, lambda v: taken.append(1) or v * 1.0)
    assert set(o) == set(onset) and "E" in o and "nothing" not in o and len(o) == len(onset)
    x = rng.uniform(1e-5, 1e-3, k)
    E = elastic_energy(law, x, o)
    assert 0 < len(taken) < len(onset)  # wrapped again in elastic_energy, still read key by key
    taken.clear()
    # the same as the dict of every key (elastic_energy's former form), value for value
    xs = x[:, None] * np.linspace(0.1, 1.0, 8)[None, :] ** 2
    o_all = {key: np.repeat(val, 8) for key, val in onset.items()}
    o_lazy = TakenOnset(onset, lambda v: taken.append(1) or np.repeat(v, 8))
    np.testing.assert_array_equal(law.contact_normal_force(xs.reshape(-1), np.zeros(xs.size), o_lazy),
                                  law.contact_normal_force(xs.reshape(-1), np.zeros(xs.size), o_all))
    assert 0 < len(taken) < len(onset)  # a normal force reads E and eta_E only
    assert np.all(E > 0.0)
