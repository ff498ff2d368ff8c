"""The compiled path of the islands (:mod:`.islands`): every island of a step
whose rows' laws the kernel knows goes through one call of
:func:`engines._island_kernel.advance_islands` per stop (an onset or an
end: ``law.onset`` and the records stay in Python, :mod:`.records`), as
:mod:`.compiled` does for rows alone. :func:`.islands.step_island` (numpy,
one island at a time) is its readable reference; tests/test_island_kernel.py
asserts the two agree.

Also here: the coupled row pairs of the step's islands (:func:`coupled_rows`)
and their blocks, set up once for all islands (both paths)."""

from __future__ import annotations

import numpy as np

from .. import _island_kernel as IK
from .. import _kernel as K
from ..contract import as_array
from .compiled import _KCST
from .islands import write_back
from .state import MAX_SEGMENTS, NY, SUBSTEPS_PER_CONTACT, _Rows, _tangent_basis, initial_state, lever_start


def coupled_rows(keys) -> tuple[np.ndarray, np.ndarray]:
    """The ordered row pairs (cp, cq) (b,) int64 with cp != cq that share a
    moving body: keys (m, 2) body keys of the rows (-1: fixed). Sorted by
    (cp, cq), each pair once: rows numbered island by island give each
    island's entries contiguous and in step_island's order."""
    m = keys.shape[0]
    idx = np.concatenate([np.arange(m), np.arange(m)])
    kk = np.concatenate([keys[:, 0], keys[:, 1]])
    on = kk >= 0
    idx, kk = idx[on], kk[on]
    o = np.argsort(kk, kind="stable")
    idx, kk = idx[o], kk[o]
    if kk.size == 0:
        return np.zeros(0, np.int64), np.zeros(0, np.int64)
    start = np.flatnonzero(np.r_[True, kk[1:] != kk[:-1]])
    size = np.diff(np.r_[start, kk.size])
    gsz = np.repeat(size, size)  # the size of each entry's key group
    gst = np.repeat(start, size)
    ii = np.repeat(idx, gsz)
    off = np.arange(int(gsz.sum())) - np.repeat(np.cumsum(gsz) - gsz, gsz)
    jj = idx[np.repeat(gst, gsz) + off]
    keep = ii != jj
    code = np.unique(ii[keep].astype(np.int64) * m + jj[keep])
    return code // m, code % m


def island_blocks(mgr, pair, multi, a):
    """The step's islands set up at once: rows R (m,) of the step (island by
    island, ascending within each), offsets io (n_isl + 1,), the coupled row
    pairs cp, cq (b,) (indices into R) with offsets cio (n_isl + 1,), the
    blocks Wpq, Wcpq (b, 3, 3) [1/kg] from the adapter, and a_ext of R with
    the neighbours' held forces taken out (their prediction sits in a_ext;
    the island couples them explicitly) (m, 3)."""
    keys_all, blocks = mgr._coupling
    sel = np.flatnonzero(multi >= 0)
    R = sel[np.argsort(multi[sel], kind="stable")]
    lab = multi[R]
    start = np.flatnonzero(np.r_[True, lab[1:] != lab[:-1]])
    io = np.r_[start, R.size].astype(np.int64)
    pp = pair[R]
    cp, cq = coupled_rows(keys_all[pp])
    isl = np.repeat(np.arange(io.size - 1), np.diff(io))
    cio = np.searchsorted(isl[cp], np.arange(io.size), side="left").astype(np.int64)
    if cp.size:
        Wpq, Wcpq = blocks(pp[cp], pp[cq])
        Wpq = as_array(Wpq, (3, 3))
        Wcpq = as_array(Wcpq, (3, 3))
    else:
        Wpq = Wcpq = np.zeros((0, 3, 3))
    a_R = a[R].copy()
    Fh = mgr._held_force[pp[cq]]
    if np.any(Fh):
        np.add.at(a_R, cp, -np.einsum("bij,bj->bi", Wpq, Fh))
    return R, io, cio, cp, cq, Wpq, Wcpq, a_R


def step_islands(mgr, p, x_eng, n, v, vc, W, Wc, a, t0, info, io, cio, cp, cq, Wpq, Wcpq, resting, L=None):
    """step_island for every island of rows p (k,) (island i: rows
    io[i]..io[i+1]-1, its coupling entries cio[i]..cio[i+1]-1 of cp, cq (b,)
    (row indices), Wpq, Wcpq (b, 3, 3)), compiled; every row's law has a
    kernel code; L (k, NL) or None: the rows' moving contact points
    (state.LEVER_DOC). Returns the impulses (k, 3) [N s]."""
    dt = mgr.dt
    k = p.size
    m = io.size - 1
    y = initial_state(mgr, p, x_eng, n, v, vc, resting, io)
    lever_start(y, L)
    Lr = np.zeros((k, K.NL)) if L is None else np.ascontiguousarray(L, dtype=float)
    t1, t2 = _tangent_basis(n)
    T = np.ascontiguousarray(np.stack([t1, t2], axis=1))
    n, W, Wc, a = (np.ascontiguousarray(q, dtype=float) for q in (n, W, Wc, a))
    Wpq, Wcpq = np.ascontiguousarray(Wpq, dtype=float), np.ascontiguousarray(Wcpq, dtype=float)
    kg = mgr._kg_of_pair[p]
    paper = mgr._paper[p]
    in_c = mgr.active[p].copy()
    t_loc = np.zeros(m)
    phase = np.zeros(m, np.int64)
    nseg = np.zeros(m, np.int64)
    ist = np.zeros(m, np.int8)
    status = np.zeros(k, np.int8)
    ended_by = np.zeros(k, np.int8)
    ints = np.zeros(4, np.int64)
    buf = np.empty(6)
    work = np.empty((5, k, NY))
    Y1, Yt, tmp = np.empty((k, NY)), np.empty((k, NY)), np.empty((k, NY))
    F = np.zeros((k, 2))
    sc = np.zeros((k, IK.NSC))
    eb = np.empty(cp.size, np.int64)  # the kernel's list of coupling entries with a force
    ri = np.zeros((k, IK.NRI), np.int64)  # and its row index scratch (marks start at zero)
    rows = _Rows(n, W, a, L)
    isl_of = np.repeat(np.arange(m), np.diff(io))
    while True:
        stopped = IK.advance_islands(_KCST, float(SUBSTEPS_PER_CONTACT), MAX_SEGMENTS, io, cio, p, n, T, W, Wc, a,
                                     paper, Lr, kg, mgr._kcodes, mgr._kLC, mgr._oc, cp, cq, Wpq, Wcpq, eb, ri, t0, dt,
                                     mgr.h, y, in_c, t_loc, phase, nseg, ist, status, ended_by, mgr.turned, mgr._fl,
                                     ints, buf, work, Y1, Yt, tmp, F, sc)
        if not stopped:
            break
        if np.any(ist == IK.IS_OVER):
            raise RuntimeError(f"more than {MAX_SEGMENTS} contact onsets/separations in one step of {dt!r} s")
        for r in np.flatnonzero(status == K.ST_ENDED).tolist():
            mgr._end(int(p[r]), y[r], float(t0 + t_loc[isl_of[r]]),
                     "force-zero" if ended_by[r] == K.END_FORCE else "overlap-zero", n[r])
            in_c[r] = False
            info["ends"] += 1
        new_all = np.flatnonzero(status == K.ST_ONSET)
        if new_all.size:
            grp = mgr._group_of[p[new_all]]
            for g in np.unique(grp):
                new = new_all[grp == g]
                mgr._begin(g, mgr._groups[g], p, new, y, rows, t0 + t_loc[isl_of[new]])
                store, pp = mgr._onset[g], p[new]
                for j, key in enumerate(K.ONSET_KEYS[mgr._kernel_law[g][0]]):
                    mgr._oc[pp, j] = store[key][mgr._pos[pp]]
            in_c[new_all] = True
            info["onsets"] += int(new_all.size)
        status[:] = K.ST_DONE
        ist[ist == IK.IS_STOP] = IK.IS_RUN
    info["segments"] += int(nseg.sum())
    info["substeps"] += int(ints[2])
    return write_back(mgr, p, n, W, Wc, y, in_c, t0, cp, cq, Wpq, Wcpq)
