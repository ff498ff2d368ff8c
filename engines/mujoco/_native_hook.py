"""The native ``mjcb_passive`` itself (engines.mujoco._native): a numba cfunc
``void(const mjModel*, mjData*)`` that calls
:func:`engines.mujoco._native_kernel.native_passive` and, when that hands the
call over, the Python hook's trampoline. Compiled once and cached (the
registry's address is an external symbol the importer registers first), in
its own module so that importing the adapter compiles nothing."""

from __future__ import annotations

from numba import cfunc, types

from engines import _kernel as K, _sweep
from engines.mujoco import _kernels as MK, _native_kernel as NK, _resting_kernel as RK
from msf_contact._jitcache import guard as _guard

# numba's cache keyed on every source compiled in (msf_contact._jitcache); before the cfunc compiles
_guard(__name__, NK, RK, K, MK, _sweep)


@cfunc(types.void(types.voidptr, types.voidptr), cache=True, error_model="numpy")
def passive(m, d):
    r = NK.native_passive(NK._registry(), NK._as_int(m), NK._as_int(d))
    if r != 0:
        NK._call_hook(r, m, d)
