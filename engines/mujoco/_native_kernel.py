"""The compiled body of the MuJoCo adapter's native ``mjcb_passive`` (issue 10).

:mod:`engines.mujoco._native` installs a numba ``cfunc`` as MuJoCo's raw
``mjcb_passive`` while the adapter's hook is installed; the
cfunc calls :func:`native_passive`, which for a registered MjData does what
the Python hook does for a resting step, with no Python in between:

1. the step tracker's test (:class:`engines.mujoco._stepping.StepTracker`,
   the semi-implicit integrators' branch): time is exactly t0 + h, MuJoCo's
   ``mj_integratePos`` of the start state, then
   :func:`engines.mujoco._kernels.off_image_start` (which also takes the
   new start state), as ``StepTracker._not_integrated`` calls them;
2. the resting step, :func:`engines.mujoco._resting_kernel.resting_step`,
   on the same arrays as :func:`engines.mujoco._resting.step` passes it
   (the same compiled function for the same types, so the same results bit
   for bit), which also applies the step's forces to ``qfrc_passive``.

Anything else is handed to the Python hook (the bindings' own trampoline of
the installed Python ``mjcb_passive``, so its exceptions propagate from
``mj_step`` as they do today): before touching anything (not registered,
not armed, a timestep, integrator or time that is not the next step's),
after the tracker's test (the state jumped: ``RESUME_JUMP``) or after the
kernel (not a resting step, or forces not all held: ``RESUME_KERNEL``); the
Python hook then goes on from where the native one stopped
(:func:`engines.mujoco._native.resume`). A call handed over disarms the
entry; the Python hook arms it again when the adapter's conditions hold.

The adapter's arrays reach this function through tables of addresses and
shapes (``ti``, int64) and scalars (``tf``, float64), one pair per adapter,
listed in a registry (``reg``) whose address the per-process cfunc holds
(layouts: the constants below). Compiled without numba's reference counting
and allocating nothing (arrays are ``numba.carray`` views of the tables'
addresses).
"""

from __future__ import annotations

import llvmlite.binding as llvm
import numpy as np
from llvmlite import ir
from numba import carray, njit, types
from numba.extending import intrinsic

from engines import _kernel as K, _sweep
from engines.mujoco import _kernels as MK, _resting_kernel as RK
from engines.mujoco._resting_kernel import RESTING, resting_step
from msf_contact._jitcache import guard as _guard

# registry (int64): the Python hook's C trampoline (the fallback), the number of slots, then per slot
# (MjData address, ti address, tf address)
R_FALLBACK, R_NSLOTS, R_SLOTS, R_MAX = 0, 1, 2, 16
R_LEN = R_SLOTS + 3 * R_MAX

# ti (int64) header: the model's address, armed, state to hand to Python (the tracker taken by a
# native call; the outputs of the last resting step done natively, in force buffer set PARITY),
# what Python resumes (RESUME_*), the tracker's q_is_q0, the expected integrator, byte offsets of
# mjData.time, mjModel.opt.timestep and mjModel.opt.integrator, mj_integratePos's address, the
# timing correction (0/1), STEPS_PER_CONTACT_MIN, the kernel's results (code, n, bad, n_hit,
# n_unheld, m), native steps done (a counter), the force buffer set the kernel wrote (RESUME_KERNEL),
# n and m of the last step done natively
(I_MODEL, I_ARMED, I_TRACK_DIRTY, I_OUT_DIRTY, I_PARITY, I_RESUME, I_Q_IS_Q0, I_INTEG, I_OFF_TIME, I_OFF_TS,
 I_OFF_INT, I_INTEGRATE, I_TIMING, I_STEPS_MIN, I_CODE, I_N, I_BAD, I_NHIT, I_NUNHELD, I_M, I_COUNT,
 I_KSET, I_LAST_N, I_LAST_M) = range(24)
I_ARRAYS = 32  # then 4 int64 per array: address, shape (3, 1 past the array's dimensions)
MAX_ARRAYS = 128
TI_LEN = I_ARRAYS + 4 * MAX_ARRAYS
# tf (float64): the tracker's t0 (of the last step taken natively), dt, settle_rate, the candidate
# factor, COINCIDENT_RTOL, TOUCH_TOL, SETTLE_AFTER_DURATIONS, JUMP_VTOL, the start time of the last
# step done natively
F_T0, F_DT, F_SETTLE_RATE, F_FACTOR, F_COINCIDENT, F_TOUCH, F_SETTLE_AFTER, F_VTOL, F_LAST_T0 = range(9)
TF_LEN = 9
# what the Python hook resumes: nothing (classify the call), the tracker's "jump" (bad_q filled), the
# step after the kernel (its results in ti)
RESUME_NONE, RESUME_JUMP, RESUME_KERNEL = 0, 1, 2

# the arrays' positions in ti: the tracker's (MjData qpos, qvel; its q0, v[0], _q, _bad_q), MjData's
# qfrc_passive, the two force buffer sets (force, point, pair), then resting_step's array arguments
# after pair_c, in its order (ARG_KINDS: dtype letter and ndim; "s" a scalar, passed from tf / ti)
A_QPOS, A_QVEL, A_Q0, A_V0, A_QIMG, A_BADQ, A_QFRC, A_FORCE, A_POINT, A_PAIR = 0, 1, 2, 3, 4, 5, 6, 7, 9, 11
A_ARGS = 13
ARG_KINDS = ("i2 f2 i1 i1 f2 f2 f2 f2 f2 f2 f2 f2 b1 f2 f2 b1 s s f1 f2 b1 b1 f2 i1 f1 f2 f2 f2 f2 f3 f3 f2 f2 f2 "
             "f2 f1 f2 f2 b1 b1 f2 b1 f2 f2 f2 f2 f1 b1 b1 f1 f1 f1 f1 f1 f1 f1 f2 s b1 i1 f1 i1 b1 i1 b1 f2 i1 f2 "
             "f2 f2 f1 f1 f1 f1 f1 f2 f3 f1 b1 b1 c1 b1 f2 i1 f1 f3 f2 f2 f2 c1 b1 f2 f2 b1 f1 s s b1 b1 i2 f2 "
             "f2").split()


@intrinsic
def _vp(typingctx, addr):
    """The address (int64) as a void pointer."""
    def codegen(context, builder, sig, args):
        return builder.inttoptr(args[0], ir.IntType(8).as_pointer())
    return types.voidptr(types.int64), codegen


#: the process's registry (layout above), which the native hook reads through the external symbol
#: REGISTRY_SYMBOL: registered with LLVM (llvmlite.binding.add_symbol) here, at import, so before
#: engines.mujoco._native_hook, which imports this module, compiles the hook or loads it from
#: numba's cache (a hook loaded before the symbol is known reads address 0)
REGISTRY = np.zeros(R_LEN, np.int64)
REGISTRY_SYMBOL = "msf_contact_native_passive_registry"
llvm.add_symbol(REGISTRY_SYMBOL, int(REGISTRY.ctypes.data))


@intrinsic
def _registry(typingctx):
    """The registry's address: the address of the external symbol REGISTRY_SYMBOL (resolved
    when the compiled code is loaded, so the code can be cached)."""
    def codegen(context, builder, sig, args):
        mod = builder.module
        gv = mod.globals.get(REGISTRY_SYMBOL)
        if gv is None:
            gv = ir.GlobalVariable(mod, ir.IntType(64), REGISTRY_SYMBOL)
        return builder.ptrtoint(gv, ir.IntType(64))
    return types.int64(), codegen


@intrinsic
def _plain(typingctx, value):
    """The int64 as a plain int64 (a constant of the caller is typed as its literal, for which the
    callee would be compiled again instead of loaded from numba's cache)."""
    def codegen(context, builder, sig, args):
        return args[0]
    return types.int64(types.int64), codegen


@intrinsic
def _as_int(typingctx, ptr):
    """The void pointer as an int64 address."""
    def codegen(context, builder, sig, args):
        return builder.ptrtoint(args[0], ir.IntType(64))
    return types.int64(types.voidptr), codegen


@intrinsic
def _call_hook(typingctx, fn, m, d):
    """Call the ``void (const mjModel*, mjData*)`` function at address fn (int64)."""
    def codegen(context, builder, sig, args):
        vp = ir.IntType(8).as_pointer()
        f = builder.inttoptr(args[0], ir.FunctionType(ir.VoidType(), [vp, vp]).as_pointer())
        builder.call(f, [args[1], args[2]])
        return context.get_dummy_value()
    return types.void(types.int64, types.voidptr, types.voidptr), codegen


@intrinsic
def _load_f8(typingctx, addr):
    """The double at the address (int64)."""
    def codegen(context, builder, sig, args):
        return builder.load(builder.inttoptr(args[0], ir.DoubleType().as_pointer()))
    return types.float64(types.int64), codegen


@intrinsic
def _load_i4(typingctx, addr):
    """The int32 at the address (int64), widened."""
    def codegen(context, builder, sig, args):
        return builder.sext(builder.load(builder.inttoptr(args[0], ir.IntType(32).as_pointer())), ir.IntType(64))
    return types.int64(types.int64), codegen


@intrinsic
def _integrate_pos(typingctx, fn, m, qpos, qvel, h):
    """MuJoCo's ``void mj_integratePos(const mjModel* m, mjtNum* qpos, const mjtNum* qvel,
    mjtNum dt)`` at address fn (int64), for m (int64) and the arrays' data."""
    def codegen(context, builder, sig, args):
        vp = ir.IntType(8).as_pointer()
        fnty = ir.FunctionType(ir.VoidType(), [vp, ir.DoubleType().as_pointer(), ir.DoubleType().as_pointer(),
                                               ir.DoubleType()])
        f = builder.inttoptr(args[0], fnty.as_pointer())
        q = context.make_array(sig.args[2])(context, builder, args[2]).data
        v = context.make_array(sig.args[3])(context, builder, args[3]).data
        builder.call(f, [builder.inttoptr(args[1], vp), q, v, args[4]])
        return context.get_dummy_value()
    return types.void(types.int64, types.int64, qpos, qvel, types.float64), codegen


# the arrays' dtypes (numba.carray's dtype argument)
F8, I8, B1, I1 = np.float64, np.int64, np.bool_, np.int8


@njit
def _a1(ti, j, dtype):
    """Array j of ti (its address and shape), 1-d."""
    r = I_ARRAYS + 4 * j
    return carray(_vp(ti[r]), (ti[r + 1],), dtype)


@njit
def _a2(ti, j, dtype):
    """Array j of ti, 2-d."""
    r = I_ARRAYS + 4 * j
    return carray(_vp(ti[r]), (ti[r + 1], ti[r + 2]), dtype)


@njit
def _a3(ti, j, dtype):
    """Array j of ti, 3-d."""
    r = I_ARRAYS + 4 * j
    return carray(_vp(ti[r]), (ti[r + 1], ti[r + 2], ti[r + 3]), dtype)


@njit(cache=True, error_model="numpy")
def native_passive(reg_addr, m, d):
    """One ``mjcb_passive`` call for the MjData at address d (int64; m: its mjModel's) with the
    registry at reg_addr (module docstring). Returns 0 when the call is done, else the address of
    the Python hook's trampoline, which the caller calls with (m, d)."""
    reg = carray(_vp(reg_addr), (R_LEN,), np.int64)
    fallback = reg[R_FALLBACK]
    ti_addr, tf_addr = 0, 0
    for s in range(reg[R_NSLOTS]):
        if reg[R_SLOTS + 3 * s] == d:
            ti_addr, tf_addr = reg[R_SLOTS + 3 * s + 1], reg[R_SLOTS + 3 * s + 2]
            break
    if ti_addr == 0:
        return fallback
    ti = carray(_vp(ti_addr), (TI_LEN,), np.int64)
    tf = carray(_vp(tf_addr), (TF_LEN,), np.float64)
    # the arrays' positions as a run-time int64 (z + j): a constant position is typed as its literal, and
    # each helper would be compiled once per position
    z = _plain(0)
    if ti[I_ARMED] == 0 or m != ti[I_MODEL]:
        return fallback
    h = _load_f8(m + ti[I_OFF_TS])
    t = _load_f8(d + ti[I_OFF_TIME])
    if h != tf[F_DT] or _load_i4(m + ti[I_OFF_INT]) != ti[I_INTEG] or t != tf[F_T0] + h:
        ti[I_ARMED] = 0
        return fallback
    # 1. the tracker (StepTracker.classify -> _not_integrated -> _start, semi-implicit integrators)
    qpos, qvel, q0, v0 = _a1(ti, z + A_QPOS, F8), _a1(ti, z + A_QVEL, F8), _a1(ti, z + A_Q0, F8), _a1(ti, z + A_V0, F8)
    q_img, bad_q = _a1(ti, z + A_QIMG, F8), _a1(ti, z + A_BADQ, B1)
    if ti[I_Q_IS_Q0] == 0:
        for i in range(q0.shape[0]):
            q_img[i] = q0[i]
    _integrate_pos(ti[I_INTEGRATE], m, q_img, qvel, h)
    off = MK.off_image_start(q_img, qpos, q0, qvel, v0, h, tf[F_VTOL], bad_q)
    ti[I_Q_IS_Q0] = 1
    tf[F_T0] = t
    ti[I_TRACK_DIRTY] = 1
    if off:
        ti[I_ARMED] = 0
        ti[I_RESUME] = RESUME_JUMP
        return fallback
    # 2. the resting step (engines.mujoco._resting.step), into the force buffer set not holding the
    # outputs of the last native step (Python may still have to make them its ContactForces)
    p = 1 - ti[I_PARITY] if ti[I_OUT_DIRTY] else ti[I_PARITY]
    code, n, bad, n_hit, n_unheld, mm = resting_step(
        t, h, tf[F_SETTLE_RATE], ti[I_TIMING] != 0, _a1(ti, z + A_QFRC, F8), _a2(ti, z + A_FORCE + p, F8),
        _a2(ti, z + A_POINT + p, F8), _a1(ti, z + A_PAIR + p, I8), _a2(ti, z + 13, I8), _a2(ti, z + 14, F8),
        _a1(ti, z + 15, I8), _a1(ti, z + 16, I8), _a2(ti, z + 17, F8), _a2(ti, z + 18, F8), _a2(ti, z + 19, F8),
        _a2(ti, z + 20, F8), _a2(ti, z + 21, F8), _a2(ti, z + 22, F8), _a2(ti, z + 23, F8), _a2(ti, z + 24, F8),
        _a1(ti, z + 25, B1), _a2(ti, z + 26, F8), _a2(ti, z + 27, F8), _a1(ti, z + 28, B1), tf[F_FACTOR],
        tf[F_COINCIDENT], _a1(ti, z + 29, F8), _a2(ti, z + 30, F8), _a1(ti, z + 31, B1), _a1(ti, z + 32, B1),
        _a2(ti, z + 33, F8), _a1(ti, z + 34, I8), _a1(ti, z + 35, F8), _a2(ti, z + 36, F8), _a2(ti, z + 37, F8),
        _a2(ti, z + 38, F8), _a2(ti, z + 39, F8), _a3(ti, z + 40, F8), _a3(ti, z + 41, F8), _a2(ti, z + 42, F8),
        _a2(ti, z + 43, F8), _a2(ti, z + 44, F8), _a2(ti, z + 45, F8), _a1(ti, z + 46, F8), _a2(ti, z + 47, F8),
        _a2(ti, z + 48, F8), _a1(ti, z + 49, B1), _a1(ti, z + 50, B1), _a2(ti, z + 51, F8), _a1(ti, z + 52, B1),
        _a2(ti, z + 53, F8), _a2(ti, z + 54, F8), _a2(ti, z + 55, F8), _a2(ti, z + 56, F8), _a1(ti, z + 57, F8),
        _a1(ti, z + 58, B1), _a1(ti, z + 59, B1), _a1(ti, z + 60, F8), _a1(ti, z + 61, F8), _a1(ti, z + 62, F8),
        _a1(ti, z + 63, F8), _a1(ti, z + 64, F8), _a1(ti, z + 65, F8), _a1(ti, z + 66, F8), _a2(ti, z + 67, F8),
        tf[F_TOUCH], _a1(ti, z + 68, B1), _a1(ti, z + 69, I8), _a1(ti, z + 70, F8), _a1(ti, z + 71, I8),
        _a1(ti, z + 72, B1), _a1(ti, z + 73, I8), _a1(ti, z + 74, B1), _a2(ti, z + 75, F8), _a1(ti, z + 76, I8),
        _a2(ti, z + 77, F8), _a2(ti, z + 78, F8), _a2(ti, z + 79, F8), _a1(ti, z + 80, F8), _a1(ti, z + 81, F8),
        _a1(ti, z + 82, F8), _a1(ti, z + 83, F8), _a1(ti, z + 84, F8), _a2(ti, z + 85, F8), _a3(ti, z + 86, F8),
        _a1(ti, z + 87, F8), _a1(ti, z + 88, B1), _a1(ti, z + 89, B1), _a1(ti, z + 90, I1), _a1(ti, z + 91, B1),
        _a2(ti, z + 92, F8), _a1(ti, z + 93, I8), _a1(ti, z + 94, F8), _a3(ti, z + 95, F8), _a2(ti, z + 96, F8),
        _a2(ti, z + 97, F8), _a2(ti, z + 98, F8), _a1(ti, z + 99, I1), _a1(ti, z + 100, B1), _a2(ti, z + 101, F8),
        _a2(ti, z + 102, F8), _a1(ti, z + 103, B1), _a1(ti, z + 104, F8), tf[F_SETTLE_AFTER], ti[I_STEPS_MIN],
        _a1(ti, z + 105, B1), _a1(ti, z + 106, B1), _a2(ti, z + 107, I8), _a2(ti, z + 108, F8), _a2(ti, z + 109, F8))
    ti[I_CODE], ti[I_N], ti[I_BAD], ti[I_NHIT], ti[I_NUNHELD], ti[I_M] = code, n, bad, n_hit, n_unheld, mm
    if code == RESTING and n_hit != 0 and mm != 0 and n_unheld == 0:  # done, forces applied (_resting.step)
        ti[I_PARITY] = p
        ti[I_LAST_N], ti[I_LAST_M] = n, mm
        tf[F_LAST_T0] = t
        ti[I_OUT_DIRTY] = 1
        ti[I_COUNT] += 1
        return 0
    ti[I_ARMED] = 0
    ti[I_RESUME] = RESUME_KERNEL
    ti[I_KSET] = p
    return fallback


# numba's cache keyed on every source compiled in (msf_contact._jitcache)
_guard(__name__, RK, K, MK, _sweep)
