"""A native ``mjcb_passive`` for the MuJoCo adapter's resting steps (issue 10).

After MuJoCo's step the Python hook's first operations run with the
interpreter's caches cold (docs/benchmarks.md: ~25-45 us of Python and
argument passing a step at N = 1,000 resting spheres, beside ~200 us of
compiled work). While :meth:`engines.mujoco.MujocoAdapter.step` runs its
loop of ``mj_step``, this module puts a numba ``cfunc`` in MuJoCo's raw
``mjcb_passive`` pointer in front of the Python hook: it calls
:func:`engines.mujoco._native_kernel.native_passive`, which does the step
tracker's test and the resting step in compiled code
(:mod:`engines.mujoco._resting`: the same compiled function on the same
arrays, so the same results bit for bit, tests/test_native_passive.py), and
hands every other call to the Python hook through the bindings' own
trampoline (the C function the bindings put in ``mjcb_passive`` for the
installed Python hook: its exceptions propagate from ``mj_step`` as before,
and ``mujoco.get_mjcb_passive()`` still returns the Python hook).

What the Python hook would have left on the adapter, the tracker and the
manager after a step done natively (the step's ContactForces, the
kinematics' time, ``last_step_info``, the tracker's start time) is written
by :func:`sync` when Python next looks: at the next call of the Python hook
and when ``step`` returns (or raises). A call the native hook hands over
after it began (the state jumped, or the kernel found the step not a
resting one) is resumed by the Python hook from there (:meth:`Native.passive`).

When it is used: only inside ``MujocoAdapter.step(n)`` for n > 1 called from
the main thread (one step alone: its set-up and hand-over cost about what it
saves; no user code runs
between its steps, so the conditions the Python hook checks each step,
:func:`engines.mujoco._resting.eligible`, and the scalars it passes cannot
change behind the native hook's back), for an adapter whose resting step is
compiled (``_fused_static``), with no Python hook chained before the
adapter's, no MSF sensors, a semi-implicit integrator, and the MjData and
MjModel fields it reads found at verified offsets (:func:`_offsets`). The
entry is armed again by the Python hook after each call it handled. A
user's own ``mj_step`` loop, ``mujoco.rollout`` and the other MjData of a
process run through the Python hook as before.
"""

from __future__ import annotations

import ctypes
import glob
import os
import struct
import threading

import mujoco
import numpy as np

from engines.mujoco import _native_kernel as NK
from engines.mujoco._stepping import JUMP_VTOL

#: the per-process registry the cfunc reads (engines.mujoco._native_kernel.REGISTRY)
_REG = NK.REGISTRY
_STATE: dict = {}  # "lib", "slot" (the raw mjcb_passive pointer), "cfunc", "offsets", "unavailable"
_CODE = {np.dtype(np.float64): "f", np.dtype(np.int64): "i", np.dtype(np.bool_): "b", np.dtype(np.int8): "c"}
_RK4 = int(mujoco.mjtIntegrator.mjINT_RK4)


def _library():
    """(libmujoco as ctypes.CDLL, its mjcb_passive pointer as c_void_p), or None when the
    library the bindings load is not found beside them."""
    if "lib" not in _STATE:
        here = os.path.dirname(mujoco.__file__)
        found = sorted(glob.glob(os.path.join(here, "libmujoco.so*")) +
                       glob.glob(os.path.join(here, "libmujoco*.dylib")))
        lib = slot = None
        if found:
            try:
                lib = ctypes.CDLL(found[0])
                slot = ctypes.c_void_p.in_dll(lib, "mjcb_passive")
            except (OSError, ValueError):
                lib = slot = None
        _STATE["lib"], _STATE["slot"] = lib, slot
    return (_STATE["lib"], _STATE["slot"]) if _STATE["lib"] is not None else None


def _find(addr: int, size: int, set_value, pack: str, values: tuple, start: int = 0,
          limit: int = 1 << 22):
    """The byte offset of a scalar field of the struct at ``addr``: ``set_value(v)`` writes it,
    the offset is the first (``size``-aligned, from ``start``) where the bytes read ``pack`` of
    values[0], then of values[1] after writing that. Reads whole 4 kB pages up to the one holding
    the field (mapped, since the field is there); None if not found below ``limit``."""
    set_value(values[0])
    want, page = struct.pack(pack, values[0]), 4096
    base = addr - addr % page
    for p in range(base, addr + limit, page):
        chunk = ctypes.string_at(p, page)
        for o in range(0, page, size):
            off = p + o - addr
            if off < start or chunk[o:o + size] != want:
                continue
            set_value(values[1])
            ok = ctypes.string_at(addr + off, size) == struct.pack(pack, values[1])
            set_value(values[0])
            if ok:
                return off
    return None


def _offsets(model, data) -> tuple | None:
    """Byte offsets of mjData.time, mjModel.opt.timestep and mjModel.opt.integrator, found by
    writing two distinct values to each field (restored after) and reading them back at the same
    place (:func:`_find`); the layout is the library's, so once per process. None if any is not
    found."""
    if "offsets" in _STATE:
        return _STATE["offsets"]
    t, h, integ = float(data.time), float(model.opt.timestep), int(model.opt.integrator)
    res = None
    try:
        o_time = _find(data._address, 8, lambda v: setattr(data, "time", v), "<d",
                       (1234.567890123, 9876.54321012))
        o_ts = _find(model._address, 8, lambda v: setattr(model.opt, "timestep", v), "<d",
                     (0.000123456789, 0.000987654321))
        o_int = None
        if o_ts is not None:
            other = (integ + 1) % 4, (integ + 2) % 4
            o_int = _find(model._address, 4, lambda v: setattr(model.opt, "integrator", v), "<i", other,
                          start=o_ts, limit=o_ts + 1024)
        if None not in (o_time, o_ts, o_int):
            res = (o_time, o_ts, o_int)
    finally:
        data.time, model.opt.timestep, model.opt.integrator = t, h, integ
    _STATE["offsets"] = res
    return res


def _cfunc():
    """The process's native hook (engines.mujoco._native_hook: compiled once, then loaded from numba's
    cache; the registry's address reaches it as the external symbol NK.REGISTRY_SYMBOL)."""
    cf = _STATE.get("cfunc")
    if cf is None:
        from engines.mujoco._native_hook import passive

        cf = _STATE["cfunc"] = passive
    return cf


class Native:
    """One adapter's entry: the tables native_passive reads (``ti``, ``tf``: layouts in
    engines.mujoco._native_kernel), the arrays they point into (kept alive here), the two force
    buffer sets, and whether ``MujocoAdapter.step`` is running (``scope``)."""

    def __init__(self, ad, offsets: tuple, integrate: int):
        self.ti = np.zeros(NK.TI_LEN, np.int64)
        self.tf = np.zeros(NK.TF_LEN, np.float64)
        self.ti[NK.I_MODEL] = ad.model._address
        self.ti[NK.I_OFF_TIME], self.ti[NK.I_OFF_TS], self.ti[NK.I_OFF_INT] = offsets
        self.ti[NK.I_INTEGRATE] = integrate
        self.tf[NK.F_VTOL] = JUMP_VTOL
        self.scope = False
        self.slot = -1
        self._cached = None  # the _resting._args list the tables were made from
        k = ad._gi.shape[0]
        self._sets = [(np.empty((k, 3)), np.empty((k, 3)), np.empty(k, np.int64)) for _ in range(2)]
        self._keep: list = []

    def _tables(self, ad, cached: list) -> bool:
        """Fill ti's array rows and tf's scalars from the resting step's arguments ``cached``
        (engines.mujoco._resting._args). False (not armed) when an argument is not of the kind
        native_passive reads it as (ARG_KINDS: dtype, dimensions, C order)."""
        tr, d = ad._tracker, ad.data
        qfrc, args = cached[0], cached[1]
        (f0, p0, i0), (f1, p1, i1) = self._sets
        arrays = [d.qpos, d.qvel, tr.q0, tr.v[0], tr._q, tr._bad_q, qfrc, f0, f1, p0, p1, i0, i1]
        kinds = ["f1", "f1", "f1", "f1", "f1", "b1", "f1", "f2", "f2", "f2", "f2", "i1", "i1"]
        scalars = []
        if len(args) != len(NK.ARG_KINDS):
            return False
        for a, kind in zip(args, NK.ARG_KINDS):
            if kind == "s":
                scalars.append(a)
            else:
                arrays.append(a)
                kinds.append(kind)
        if len(arrays) > NK.MAX_ARRAYS:
            return False
        for j, (a, kind) in enumerate(zip(arrays, kinds)):
            if (not isinstance(a, np.ndarray) or _CODE.get(a.dtype) != kind[0] or a.ndim != int(kind[1])
                    or not a.flags.c_contiguous):
                return False
            r = NK.I_ARRAYS + 4 * j
            self.ti[r] = a.ctypes.data
            self.ti[r + 1:r + 1 + a.ndim] = a.shape
        factor, coincident, touch, settle_after, steps_min = scalars
        tf = self.tf
        tf[NK.F_FACTOR], tf[NK.F_COINCIDENT], tf[NK.F_TOUCH], tf[NK.F_SETTLE_AFTER] = (
            float(factor), float(coincident), float(touch), float(settle_after))
        self.ti[NK.I_STEPS_MIN] = int(steps_min)
        self._keep = arrays
        self._cached = cached
        return True

    def arm(self, ad) -> None:
        """Arm the entry when the adapter's next step may be done natively (module docstring);
        called by the Python hook after each call it handled inside ``step``, and by :func:`enter`."""
        from engines.mujoco import _resting

        tr, mgr = ad._tracker, ad.manager
        a = ad._rest_args
        ok = (a is not None and a[0] is mgr._kcodes and a[1] is mgr._kLC and tr.t0 is not None and tr.stage == 0
              and not tr._taken and ad.fused and ad._known is None and not ad._sensors and ad._native_result is None
              and _resting.eligible(ad))
        if ok and a[2] is not self._cached:
            ok = self._tables(ad, a[2])
        integ = int(ad.model.opt.integrator)
        if not ok or integ == _RK4 or not ad.model.nv:
            self.ti[NK.I_ARMED] = 0
            return
        ti, tf = self.ti, self.tf
        ti[NK.I_Q_IS_Q0] = bool(tr._q_is_q0)
        ti[NK.I_INTEG] = integ
        ti[NK.I_TIMING] = bool(mgr.timing_correction)
        tf[NK.F_T0], tf[NK.F_DT], tf[NK.F_SETTLE_RATE] = tr.t0, float(mgr.dt), float(mgr.settle_rate)
        ti[NK.I_ARMED] = 1

    def sync(self, ad) -> str | None:
        """Write what the native calls since Python last looked leave on the adapter, the tracker
        and the manager (module docstring). Returns the kind of the current call when the native
        hook handed it over after beginning it ("jump": the tracker found a jump; "step": the
        kernel ran, its results kept in ``ad._native_result``), else None."""
        ti, tf = self.ti, self.tf
        if not ti[NK.I_TRACK_DIRTY]:
            return None
        from engines.mujoco import _resting

        ti[NK.I_TRACK_DIRTY] = 0
        tr = ad._tracker
        if ti[NK.I_OUT_DIRTY]:  # the last step done natively: what _resting.step leaves
            ti[NK.I_OUT_DIRTY] = 0
            force, point, pair = self._sets[int(ti[NK.I_PARITY])]
            n, m = int(ti[NK.I_LAST_N]), int(ti[NK.I_LAST_M])
            t_last = float(tf[NK.F_LAST_T0])
            _resting.finish(ad, ad._rest_args[2], force[:n].copy(), point[:n].copy(), pair[:n].copy(), n, m, t_last)
            ad._step_start = None
            ad._unheld = None
        # the tracker as StepTracker._start leaves it after the semi-implicit test
        tr.t0, tr._q_is_q0, tr._taken, tr.stage, tr.jumped = float(tf[NK.F_T0]), True, False, 0, None
        resume, ti[NK.I_RESUME] = int(ti[NK.I_RESUME]), NK.RESUME_NONE
        if resume == NK.RESUME_JUMP:  # StepTracker.classify's jump after _not_integrated found the image off
            tr.why = tr._jumped_trees(np.unique(tr._qtree[tr._bad_q]))
            return "jump"
        if resume == NK.RESUME_KERNEL:
            force, point, pair = self._sets[int(ti[NK.I_KSET])]
            ad._native_result = (int(ti[NK.I_CODE]), int(ti[NK.I_N]), int(ti[NK.I_BAD]), int(ti[NK.I_NHIT]),
                                 int(ti[NK.I_NUNHELD]), int(ti[NK.I_M]), force.copy(), point.copy(), pair.copy())
            return "step"
        return None

    def passive(self, ad, model, data) -> None:
        """The Python hook's call for this adapter: bring the Python state up to date (:meth:`sync`),
        run the Python hook (from where the native one stopped), arm again inside ``step``."""
        kind = self.sync(ad)
        ad._passive(model, data, kind if kind is not None else ad._tracker.classify(data))
        if self.scope:
            self.arm(ad)


def _usable(ad) -> bool:
    return bool(ad.compiled and ad._fused_static and ad.fused and ad._known is None and not ad._sensors)


def enter(ad, dispatch, previous: list) -> Native | None:
    """Start the native hook for ``ad`` (installed, inside its ``step``); None when it cannot be used
    (module docstring). dispatch: the adapters' Python mjcb_passive (engines.mujoco.adapter._dispatch),
    which must be the one installed; previous: the Python hook it chains (none allowed: the native
    hook would skip it). Pair with :func:`leave`."""
    if (not _usable(ad) or (previous and previous[0] is not None) or mujoco.get_mjcb_passive() is not dispatch
            or threading.current_thread() is not threading.main_thread()):  # (the registry is not locked)
        return None
    nat = ad._native
    if nat is not None and nat.slot >= 0:  # a step inside this adapter's step (from a callback): already entered
        return None
    if nat is None:
        if _STATE.get("unavailable"):
            return None
        lib = _library()
        offsets = _offsets(ad.model, ad.data) if lib is not None else None
        if offsets is None:
            _STATE["unavailable"] = True
            return None
        integrate = ctypes.cast(lib[0].mj_integratePos, ctypes.c_void_p).value
        nat = ad._native = Native(ad, offsets, integrate)
    slot_ptr = _STATE["slot"]
    cf = _cfunc()
    free = [s for s in range(NK.R_MAX) if _REG[NK.R_SLOTS + 3 * s] == 0]
    if not free:
        return None
    s = free[0]
    _REG[NK.R_SLOTS + 3 * s + 1] = nat.ti.ctypes.data
    _REG[NK.R_SLOTS + 3 * s + 2] = nat.tf.ctypes.data
    _REG[NK.R_SLOTS + 3 * s] = ad.data._address
    _REG[NK.R_NSLOTS] = max(int(_REG[NK.R_NSLOTS]), s + 1)
    nat.slot = s
    if slot_ptr.value != cf.address:  # the bindings' trampoline of the Python hook: the fallback
        _REG[NK.R_FALLBACK] = slot_ptr.value
        slot_ptr.value = cf.address
    nat.scope = True
    nat.arm(ad)
    return nat


def leave(ad, nat: Native) -> None:
    """End :func:`enter`: disarm, unregister, put the bindings' trampoline back in mjcb_passive when
    no adapter uses the native hook any more, and bring the Python state up to date."""
    nat.scope = False
    nat.ti[NK.I_ARMED] = 0
    # a call handed over is resumed by the Python hook within the same mj_step; one still pending here
    # means mj_step raised before the hook ran: the step was not completed, nothing is to resume
    nat.ti[NK.I_RESUME] = NK.RESUME_NONE
    ad._native_result = None
    s, nat.slot = nat.slot, -1
    if s >= 0:
        _REG[NK.R_SLOTS + 3 * s] = 0
        _REG[NK.R_SLOTS + 3 * s + 1] = 0
        _REG[NK.R_SLOTS + 3 * s + 2] = 0
        if not _REG[NK.R_SLOTS::3].any():
            _REG[NK.R_NSLOTS] = 0
            slot_ptr = _STATE["slot"]
            if slot_ptr.value == _STATE["cfunc"].address:
                slot_ptr.value = int(_REG[NK.R_FALLBACK])
    nat.sync(ad)
