"""A native ``mjcb_passive`` for the MuJoCo adapter's resting steps (issue 10).

After MuJoCo's step the Python hook's first operations run with the
interpreter's caches cold (docs/benchmarks.md: ~25-45 us of Python and
argument passing a step at N = 1,000 resting spheres, beside ~200 us of
compiled work). While the adapter's hook is installed, this module puts a
numba ``cfunc`` in MuJoCo's raw ``mjcb_passive`` pointer in front of the
Python hook: it calls
:func:`engines.mujoco._native_kernel.native_passive`, which does the step
tracker's test and the resting step in compiled code
(:mod:`engines.mujoco._resting`: the same compiled function on the same
arrays, so the same results bit for bit, tests/test_native_passive.py), and
hands every other call to the Python hook through the bindings' own
trampoline (the C function the bindings put in ``mjcb_passive`` for the
installed Python hook, which takes the GIL: its exceptions propagate from
``mj_step`` as before, and ``mujoco.get_mjcb_passive()`` still returns the
Python hook).

What the Python hook would have left on the adapter, the tracker and the
manager after a step done natively (the step's ContactForces, the
kinematics' time, ``last_step_info``, the tracker's start time) is written
by :meth:`Native.sync` when Python next looks: at the next call of the
Python hook, when the adapter or its manager is read (below) and when the
hook is uninstalled. A call the native hook hands over after it began (the
state jumped, or the kernel found the step not a resting one) is resumed by
the Python hook from there (:meth:`Native.passive`).

When it is used: whenever the adapter's hook is installed (:func:`attach`,
called by :func:`engines.mujoco.installed`, which ``MujocoAdapter.step``
also enters), so a user's own ``mj_step`` loop, ``step(1)``, the viewer's
loop and a gymnasium env's steps take their resting steps natively as
``step(n)`` does; for an adapter whose resting step is compiled
(``_fused_static``), with no Python hook chained before the adapter's, no
MSF sensors, a semi-implicit integrator (RK4: the Python hook, every step)
and the MjData and MjModel fields it reads found at verified offsets
(:func:`_offsets`). The entry is armed by the Python hook after a call
whose step was a resting one done in full (``MujocoAdapter._rested``: a
scene in motion, such as the jet, stays on the Python hook with no added
cost but the cfunc's look-up) and when the conditions it checks each step
hold (:meth:`Native.arm`, :func:`engines.mujoco._resting.eligible`).

Python between the steps (a user's loop): what the Python hook reads each
step from the adapter and its manager (``fused``, ``set_mode``'s pairs,
the manager's ``step``, ``settled_path``, ``settle_rate``, ``dt``, its law
tables, ...) must not change behind the native hook's back, and what a
native step leaves must be there when Python reads it. While the entry is
armed the adapter and its manager are *watched*: their
class is swapped for a subclass (:func:`_watched_class`, the same name and
methods) whose attribute read first writes what the native steps left
(:meth:`Native.catch_up`) and whose attribute write or delete hands the
next step to the Python hook (:meth:`Native.release`: disarmed, which the
Python hook arms again after its step). The swap is undone before the
Python hook runs, so the hook's own work pays nothing for it. Arrays
written in place (``manager.settled[...] = ...``) are read by the native
step as by the Python hook (the same arrays). ``MujocoAdapter.step`` reads
and counts through the adapter's ``__dict__`` (nothing a native step
leaves stale), so a loop of ``step(1)`` stays native. MuJoCo's own state (a
qpos, qvel or time written, ``mj_resetData``, ``mj_forward`` between
steps, another timestep or integrator) is checked natively each call and
handed to the Python hook.

Threads: the native step needs no GIL; an MjData is stepped by one thread
at a time (``mujoco.rollout``'s threads each step their own MjData), and
every adapter has its own tables, so calls on different MjData do not
share anything the native step writes. At most :data:`NK.R_MAX` adapters
use it at once (the next ones: the Python hook).
"""

from __future__ import annotations

import ctypes
import glob
import os
import struct

import mujoco
import numpy as np

from engines.mujoco import _native_kernel as NK
from engines.mujoco._stepping import JUMP_VTOL

#: the per-process registry the cfunc reads (engines.mujoco._native_kernel.REGISTRY)
_REG = NK.REGISTRY
_STATE: dict = {}  # "lib", "slot" (the raw mjcb_passive pointer), "cfunc", "offsets", "unavailable", "dispatch"
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
    buffer sets, its registry slot (-1: not attached) and the objects watched."""

    def __init__(self, ad, offsets: tuple, integrate: int):
        self.ad = ad
        self.ti = np.zeros(NK.TI_LEN, np.int64)
        self.tf = np.zeros(NK.TF_LEN, np.float64)
        self.ti[NK.I_MODEL] = ad.model._address
        self.ti[NK.I_OFF_TIME], self.ti[NK.I_OFF_TS], self.ti[NK.I_OFF_INT] = offsets
        self.ti[NK.I_INTEGRATE] = integrate
        self.tf[NK.F_VTOL] = JUMP_VTOL
        self.slot = -1
        self.watched: tuple = ()
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
        """Arm the entry when the adapter's next step may be done natively (module docstring):
        attached, its last step a resting one done in full (``ad._rested``), no body welded to the
        world in its pairs (the Python hook watches those for a move: ``_watch_static``) and the
        Python hook's conditions met; called by the Python hook after each call it handled and by :func:`attach`.
        Puts the native hook back in mjcb_passive when the adapters' Python hook is installed again
        without it (``mujoco.set_mjcb_passive`` of the same hook, as ``_replayed_offset`` does)."""
        from engines.mujoco import _resting

        tr, mgr = ad._tracker, ad.manager
        a = ad._rest_args
        ok = (self.slot >= 0 and ad._rested and a is not None and a[0] is mgr._kcodes and a[1] is mgr._kLC
              and tr.t0 is not None and tr.stage == 0 and not tr._taken and ad.fused and ad._known is None
              and not ad._sensors and ad._native_result is None and not ad._static_watch.size
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
        slot_ptr, cf = _STATE["slot"], _STATE["cfunc"]
        if slot_ptr.value != cf.address and mujoco.get_mjcb_passive() is _STATE["dispatch"]:
            _REG[NK.R_FALLBACK] = slot_ptr.value  # the bindings' trampoline of the Python hook
            slot_ptr.value = cf.address

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
        """The Python hook's call for this adapter: the adapter and manager no longer watched,
        the Python state brought up to date (:meth:`sync`), the Python hook run (from where the
        native one stopped), the entry armed again (and the objects watched outside ``step``)."""
        self.unwatch()
        self.ti[_ARMED] = 0
        kind = self.sync(ad)
        ad._passive(model, data, kind if kind is not None else ad._tracker.classify(data))
        if self.slot >= 0 and ad._rested:
            self.arm(ad)
            if self.ti[_ARMED]:
                self.watch()

    # -- watching the adapter and its manager between steps (module docstring) --
    def watch(self) -> None:
        ad = self.ad
        mgr = object.__getattribute__(ad, "manager")
        objs = (ad, mgr)
        for o in objs:
            cls = type(o)
            if cls not in _BASES:
                w = _watched_class(cls)
                if w is None:
                    self.unwatch()
                    self.ti[_ARMED] = 0  # a class that cannot be watched: the Python hook
                    return
                object.__setattr__(o, "__class__", w)
            _OWNERS[id(o)] = self
        self.watched = objs

    def unwatch(self) -> None:
        for o in self.watched:
            base = _BASES.get(type(o))
            if base is not None:
                object.__setattr__(o, "__class__", base)
            _OWNERS.pop(id(o), None)
        self.watched = ()

    def catch_up(self) -> None:
        """A watched object is read: write what the native steps left, watch again."""
        self.unwatch()
        self.sync(self.ad)
        if self.ti[_ARMED]:
            self.watch()

    def release(self) -> None:
        """A watched object is written: no longer watched, the next step the Python hook's."""
        self.unwatch()
        self.ti[_ARMED] = 0
        if self.ti[_RESUME] == NK.RESUME_NONE:  # (a call handed over is resumed by the Python hook)
            self.sync(self.ad)


_ARMED, _DIRTY, _RESUME = NK.I_ARMED, NK.I_TRACK_DIRTY, NK.I_RESUME
_OWNERS: dict = {}  # id(watched object) -> its Native
_BASES: dict = {}  # watched class -> the class it watches
_WATCHED: dict = {}  # class -> its watched subclass (None: cannot be watched)


#: attributes whose value no native step leaves stale, read without bringing the rest up to date (a
#: loop of ``adapter.step(1)`` and its geom check, ``adapter.data``)
_FRESH = frozenset({"step", "data", "model", "timestep", "steps", "compiled", "_kernels", "_check_geoms",
                    "_geom_shape", "_geom_ids", "_geom_shape0"})


def _get(obj, name):
    nat = _OWNERS.get(id(obj))
    if nat is not None and nat.ti[_DIRTY] and not nat.ti[_RESUME] and name not in _FRESH:
        nat.catch_up()
    return object.__getattribute__(obj, name)


#: attributes whose write changes nothing a native step reads: the records (``pop_records``), the
#: adapter's step count, and the manager's list of records waiting for their probe set empty (which
#: it is while armed: :func:`engines.mujoco._resting.eligible`)
_HARMLESS = frozenset({"records", "steps"})


def _set(obj, name, value):
    if name in _HARMLESS or (name == "_pending" and not value):
        object.__setattr__(obj, name, value)
        return
    _let_go(obj)
    setattr(obj, name, value)


def _del(obj, name):
    _let_go(obj)
    delattr(obj, name)


def _reduce_ex(obj, protocol):
    _let_go(obj)  # (copied or pickled as its own class: the watched one is not found by name)
    return obj.__reduce_ex__(protocol)


def _let_go(obj) -> None:
    nat = _OWNERS.get(id(obj))
    if nat is not None:
        nat.release()
    base = _BASES.get(type(obj))
    if base is not None:  # (not expected: a watched object whose entry let go of it)
        object.__setattr__(obj, "__class__", base)


def _watched_class(cls):
    """The subclass of ``cls`` that watches its instances (module docstring): the same name,
    module and methods, its attribute access through :func:`_get`, :func:`_set`, :func:`_del`.
    None when ``cls`` reads or writes its attributes itself (a ``__getattribute__``,
    ``__setattr__`` or ``__delattr__`` of its own) or its instances have no ``__dict__`` or no weak
    references (the subclass would add them: another layout, which ``__class__`` cannot take)."""
    if cls in _WATCHED:
        return _WATCHED[cls]
    own = any(getattr(cls, n) is not getattr(object, n) for n in ("__getattribute__", "__setattr__", "__delattr__"))
    w = None
    if not own and cls.__dictoffset__ and cls.__weakrefoffset__:  # (the subclass adds no slot: the same layout)
        ns = {"__getattribute__": _get, "__setattr__": _set, "__delattr__": _del, "__reduce_ex__": _reduce_ex,
              "__module__": cls.__module__,
              "__qualname__": cls.__qualname__, "__doc__": cls.__doc__}
        w = type(cls)(cls.__name__, (cls,), ns)
        _BASES[w] = cls
    _WATCHED[cls] = w
    return w


def _usable(ad) -> bool:
    return bool(ad.compiled and ad._fused_static and ad._known is None and not ad._sensors)


def attach(ad, dispatch, previous: list) -> None:
    """Start the native hook for ``ad`` (called by ``installed`` once the adapters' Python hook
    ``dispatch`` is in mjcb_passive); nothing when it cannot be used (module docstring).
    previous: the Python hook ``dispatch`` chains (none allowed: the native hook would skip it).
    Pair with :func:`detach`."""
    if not _usable(ad) or (previous and previous[0] is not None) or mujoco.get_mjcb_passive() is not dispatch:
        return
    nat = ad._native
    if nat is not None and nat.slot >= 0:
        return
    if nat is None:
        if _STATE.get("unavailable"):
            return
        lib = _library()
        offsets = _offsets(ad.model, ad.data) if lib is not None else None
        if offsets is None:
            _STATE["unavailable"] = True
            return
        integrate = ctypes.cast(lib[0].mj_integratePos, ctypes.c_void_p).value
        nat = ad._native = Native(ad, offsets, integrate)
    _STATE["dispatch"] = dispatch
    _cfunc()
    free = [s for s in range(NK.R_MAX) if _REG[NK.R_SLOTS + 3 * s] == 0]
    if not free:
        return
    s = free[0]
    _REG[NK.R_SLOTS + 3 * s + 1] = nat.ti.ctypes.data
    _REG[NK.R_SLOTS + 3 * s + 2] = nat.tf.ctypes.data
    _REG[NK.R_SLOTS + 3 * s] = ad.data._address
    _REG[NK.R_NSLOTS] = max(int(_REG[NK.R_NSLOTS]), s + 1)
    nat.slot = s
    nat.arm(ad)  # (puts the native hook in mjcb_passive)
    if nat.ti[_ARMED]:
        nat.watch()


def detach(ad) -> None:
    """End :func:`attach`: no longer watched, disarmed, the Python state brought up to date,
    unregistered, and the bindings' trampoline back in mjcb_passive when no adapter uses the
    native hook any more."""
    nat = object.__getattribute__(ad, "_native")
    if nat is None or nat.slot < 0:
        return
    nat.unwatch()
    nat.ti[_ARMED] = 0
    # a call handed over is resumed by the Python hook within the same mj_step; one still pending here
    # means mj_step raised before the hook ran: the step was not completed, nothing is to resume
    nat.ti[_RESUME] = NK.RESUME_NONE
    ad._native_result = None
    nat.sync(ad)
    s, nat.slot = nat.slot, -1
    _REG[NK.R_SLOTS + 3 * s] = 0
    _REG[NK.R_SLOTS + 3 * s + 1] = 0
    _REG[NK.R_SLOTS + 3 * s + 2] = 0
    if not _REG[NK.R_SLOTS::3].any():
        _REG[NK.R_NSLOTS] = 0
        slot_ptr = _STATE["slot"]
        if slot_ptr.value == _STATE["cfunc"].address:
            slot_ptr.value = int(_REG[NK.R_FALLBACK])
