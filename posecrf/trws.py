"""TRW-S: sequential tree-reweighted message passing for pairwise MRFs.

Kolmogorov, "Convergent tree-reweighted message passing for energy
minimization", PAMI 2006. The paper solves its pose CRF with it (Sec. 3.2,
100 iterations, Sec. 4). :func:`trws` runs compiled kernels (numba) with
messages on structured grid edges computed by Felzenszwalb-Huttenlocher
distance transforms (linear in the labels per grid axis, separable across
axes); :func:`trws_naive` is a plain numpy implementation of the same
schedule with dense O(L^2) messages, kept as a peer for tests and benchmarks.

Convention: costs, lower is better (see :mod:`posecrf.mrf`). Nodes are
processed in ``order`` (default ``0..N-1``); a forward pass sends messages to
later nodes, a backward pass to earlier ones and yields the lower bound, which
never decreases from one iteration to the next. Each node weighs its
belief by ``1 / max(#earlier neighbours, #later neighbours)`` (monotonic
chains). After every iteration a labelling is decoded in ``order`` and the
best one seen is returned.
"""

from __future__ import annotations

import importlib.util
import math
import sys
import types
from dataclasses import dataclass
from pathlib import Path
from typing import Literal

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .mrf import GridCost, PairwiseMRF, energy

__all__ = ["TRWSResult", "trws", "trws_naive", "grid_message", "dense_message", "backend"]

Backend = Literal["auto", "numba", "python"]

_REASONS = {0: "max_iter reached", 1: "duality gap closed (labelling is optimal)", 2: "lower bound stalled"}
_KERNELS: dict[str, types.ModuleType] = {}


def _kernels(which: Backend = "auto") -> types.ModuleType:
    """The kernel module: numba-compiled when possible, or the same code as plain Python."""
    if which not in ("auto", "numba", "python"):
        raise ValueError(f"backend: expected 'auto', 'numba' or 'python', got {which!r}")
    if which in ("auto", "numba"):
        from . import _trws_kernels as k

        if which == "numba" and k.BACKEND != "numba":
            raise ImportError("backend='numba' needs numba: pip install numba")
        return k
    if "python" not in _KERNELS:
        path = Path(__file__).with_name("_trws_kernels.py")
        spec = importlib.util.spec_from_file_location("posecrf._trws_kernels_python", path)
        assert spec is not None and spec.loader is not None
        mod = importlib.util.module_from_spec(spec)
        mod.__dict__["_PANO2CAD_FORCE_PYTHON"] = True
        sys.modules[spec.name] = mod
        spec.loader.exec_module(mod)
        _KERNELS["python"] = mod
    return _KERNELS["python"]


def backend() -> str:
    """Which backend ``trws(..., backend="auto")`` uses here: ``"numba"`` or ``"python"``."""
    return str(_kernels("auto").BACKEND)


@dataclass(frozen=True)
class TRWSResult:
    """Result of :func:`trws` / :func:`trws_naive`.

    Attributes
    ----------
    labels : (N,) int
        Best labelling decoded over all iterations.
    energy : float
        Its energy (:func:`posecrf.mrf.energy`).
    lower_bound : float
        Largest lower bound on the minimum energy seen (the last one: the
        bound does not decrease).
    iterations : int
        Iterations run (one = forward + backward pass).
    converged : bool
        True when the run stopped because the duality gap closed or the bound
        stalled (improved by at most ``tol * max(1, |bound|)``), not at ``max_iter``.
    reason : str
        Why it stopped.
    lower_bounds, energies : (iterations,) float
        Bound and decoded energy after each iteration.
    backend : str
        "numba", "python" or "naive".
    """

    labels: NDArray[np.int64]
    energy: float
    lower_bound: float
    iterations: int
    converged: bool
    reason: str
    lower_bounds: NDArray[np.float64]
    energies: NDArray[np.float64]
    backend: str

    @property
    def gap(self) -> float:
        """energy - lower_bound (>= 0 up to rounding; 0 proves optimality)."""
        return self.energy - self.lower_bound


def _check_common(
    mrf: PairwiseMRF, max_iter: int, tol: float | None, order: ArrayLike | None
) -> tuple[int, float, NDArray[np.int64]]:
    if not isinstance(mrf, PairwiseMRF):
        raise ValueError(f"mrf: expected a PairwiseMRF, got {type(mrf).__name__}")
    if int(max_iter) != max_iter or max_iter < 1:
        raise ValueError(f"max_iter: expected a positive integer, got {max_iter!r}")
    if tol is None:
        t = -1.0
    else:
        t = float(tol)
        if not (t >= 0 and math.isfinite(t)):
            raise ValueError(f"tol: expected a finite tol >= 0 or None (never stop early), got {tol!r}")
    n = mrf.n_nodes
    if order is None:
        o = np.arange(n, dtype=np.int64)
    else:
        oa = np.asarray(order)
        if oa.shape != (n,) or not np.issubdtype(oa.dtype, np.integer) or not np.array_equal(np.sort(oa), np.arange(n)):
            raise ValueError(
                f"order: expected a permutation of 0..{n - 1} (shape ({n},)), got shape {oa.shape} dtype {oa.dtype}"
            )
        o = oa.astype(np.int64)
    return int(max_iter), t, o


def trws(
    mrf: PairwiseMRF,
    *,
    max_iter: int = 100,
    tol: float | None = 1e-9,
    order: ArrayLike | None = None,
    backend: Backend = "auto",
) -> TRWSResult:
    """Minimise the energy of a pairwise MRF with TRW-S.

    Parameters
    ----------
    mrf : PairwiseMRF
    max_iter : int
        Maximum number of iterations (forward + backward pass each); the paper uses 100.
    tol : float or None
        Stop when an iteration raises the bound by at most ``tol * max(1, |bound|)``;
        None never stops early (except when the duality gap closes).
    order : (N,) int, optional
        Node processing order (a permutation); default ``0..N-1``.
    backend : {"auto", "numba", "python"}
        "auto" uses numba when it is installed. "python" runs the same
        kernels uncompiled (slow; for checks). Results are identical.

    Returns
    -------
    TRWSResult

    Convention: see the module docstring. Grid edges use distance-transform
    messages in O(L * ndim); dense edges O(L_i * L_j).

    Examples
    --------
    A stereo-like scanline: 6 pixels, 4 disparities, data costs favour
    disparity 1 on the left and 3 on the right, pixel 2 is noisy (prefers 0);
    truncated-linear smoothness removes the outlier and keeps the one jump.

    >>> from posecrf.mrf import GridCost, LabelGrid, PairwiseMRF
    >>> data = np.array([[3, 0, 3, 3], [3, 0, 3, 3], [0.4, 1, 3, 3],
    ...                  [3, 0, 3, 3], [3, 3, 3, 0], [3, 3, 3, 0]])
    >>> mrf = PairwiseMRF(data)
    >>> smooth = GridCost(LabelGrid((4,)), weight=1.0, gamma=2.0)
    >>> for i in range(5):
    ...     _ = mrf.add_grid_edge(i, i + 1, smooth)
    >>> res = trws(mrf)
    >>> res.labels.tolist(), res.energy, res.converged
    ([1, 1, 1, 1, 3, 3], 3.0, True)
    """
    n_iter, t, order_arr = _check_common(mrf, max_iter, tol, order)
    k = _kernels(backend)
    ar = mrf.as_arrays()
    n = ar.n_nodes
    pos, gnode = k.order_weights(order_arr, ar.ea, ar.eb, n)
    adj_ptr, adj_edge = _adjacency(ar.ea, ar.eb, n)
    n_lab = np.diff(ar.lab_off)
    la = n_lab[ar.ea]
    lb = n_lab[ar.eb]
    moff_a = np.zeros(ar.n_edges, dtype=np.int64)
    moff_b = np.zeros(ar.n_edges, dtype=np.int64)
    if ar.n_edges:
        sizes = np.stack([la, lb], axis=1).ravel()
        starts = np.concatenate([[0], np.cumsum(sizes)[:-1]])
        moff_a[:] = starts[0::2]
        moff_b[:] = starts[1::2]
        msg = np.zeros(int(sizes.sum()), dtype=np.float64)
    else:
        msg = np.zeros(1, dtype=np.float64)
    lb_hist = np.zeros(n_iter, dtype=np.float64)
    e_hist = np.zeros(n_iter, dtype=np.float64)
    labels = np.zeros(n, dtype=np.int64)
    best = np.zeros(n, dtype=np.int64)
    max_n = int(ar.g_shape.max()) if ar.g_shape.size else 1
    args = (
        n_iter, t, ar.lab_off, ar.unary, order_arr, pos, ar.ea, ar.eb, ar.kind, ar.cost_off, ar.costs,
        ar.gid, ar.weight, ar.gamma, ar.g_ndim, ar.g_shape, ar.g_step, ar.g_cyc, adj_ptr, adj_edge, gnode,
        msg, moff_a, moff_b, lb_hist, e_hist, labels, best, int(n_lab.max()), max_n,
    )
    with np.errstate(over="ignore", divide="ignore"):  # the Python backend computes with numpy scalars
        done, status = k.run(*args)
    return _result(mrf, best, lb_hist[:done], e_hist[:done], int(done), int(status), str(k.BACKEND))


def _adjacency(ea: NDArray[np.int64], eb: NDArray[np.int64], n: int) -> tuple[NDArray[np.int64], NDArray[np.int64]]:
    """CSR incidence lists: edges of node i are adj_edge[adj_ptr[i]:adj_ptr[i+1]], in edge order."""
    ends = np.concatenate([ea, eb])
    eid = np.concatenate([np.arange(ea.shape[0]), np.arange(ea.shape[0])]).astype(np.int64)
    srt = np.lexsort((eid, ends))
    adj_edge = eid[srt]
    adj_ptr = np.zeros(n + 1, dtype=np.int64)
    np.cumsum(np.bincount(ends, minlength=n), out=adj_ptr[1:])
    return adj_ptr, adj_edge


def _result(mrf: PairwiseMRF, labels: NDArray[np.int64], lbs: NDArray[np.float64], es: NDArray[np.float64],
            done: int, status: int, backend_name: str) -> TRWSResult:
    lbs = lbs.copy()
    es = es.copy()
    lab = labels.copy()
    for a in (lbs, es, lab):
        a.setflags(write=False)
    return TRWSResult(
        labels=lab,
        energy=energy(mrf, lab),
        lower_bound=float(np.max(lbs)),
        iterations=done,
        converged=status != 0,
        reason=_REASONS[status],
        lower_bounds=lbs,
        energies=es,
        backend=backend_name,
    )


def grid_message(h: ArrayLike, cost: GridCost, *, backend: Backend = "auto") -> NDArray[np.float64]:
    """Min-sum message over a grid cost by distance transforms: ``m[x] = min_y h[y] + cost(y, x)``.

    Parameters
    ----------
    h : (L,) float
        Finite costs over the grid's labels.
    cost : GridCost

    Returns
    -------
    m : (L,) float
        Equal (up to rounding) to ``dense_message(h, cost.dense())``, computed in
        O(L * ndim): Felzenszwalb-Huttenlocher passes per axis, then
        ``min(., min(h) + weight * gamma)``.

    Convention: grid labels in C order (:class:`posecrf.mrf.LabelGrid`).

    Examples
    --------
    >>> from posecrf.mrf import GridCost, LabelGrid
    >>> c = GridCost(LabelGrid((6,), cyclic=(True,)), weight=1.0, gamma=2.5)
    >>> grid_message([0.0, 9, 9, 9, 9, 9], c).tolist()
    [0.0, 1.0, 2.0, 2.5, 2.0, 1.0]
    """
    if not isinstance(cost, GridCost):
        raise ValueError(f"cost: expected a GridCost, got {type(cost).__name__}")
    g = cost.grid
    hv = np.asarray(h, dtype=np.float64)
    if hv.shape != (g.size,):
        raise ValueError(f"h: expected shape (L,) = ({g.size},), got {hv.shape}")
    if not np.all(np.isfinite(hv)):
        raise ValueError("h: expected finite costs, got NaN or inf")
    k = _kernels(backend)
    hmin = float(hv.min())
    out = hv - hmin
    m = 3 * max(g.shape) + 3
    axes = [np.array(g.shape, dtype=np.int64), np.array(g.steps, dtype=np.float64), np.array(g.cyclic, dtype=np.int64)]
    for a in axes:
        a.setflags(write=False)  # as in MRFArrays: one compiled signature serves both callers
    with np.errstate(over="ignore", divide="ignore"):
        k.grid_dt(
            out, g.ndim, *axes, cost.weight, cost.gamma, 1 if cost.metric == "l1" else 2,
            np.empty(m), np.empty(m), np.empty(m, dtype=np.int64), np.empty(m + 1),
        )
    out += hmin
    return out


def dense_message(h: ArrayLike, cost: ArrayLike) -> NDArray[np.float64]:
    """Min-sum message through a dense cost: ``m[x] = min_y h[y] + cost[y, x]``.

    Parameters
    ----------
    h : (L_a,) float
    cost : (L_a, L_b) float

    Returns
    -------
    m : (L_b,) float

    Examples
    --------
    >>> dense_message([0.0, 5.0], [[1.0, 4.0], [0.0, 0.0]]).tolist()
    [1.0, 4.0]
    """
    hv = np.asarray(h, dtype=np.float64)
    c = np.asarray(cost, dtype=np.float64)
    if hv.ndim != 1 or c.ndim != 2 or c.shape[0] != hv.shape[0]:
        raise ValueError(f"expected h (L_a,) and cost (L_a, L_b), got {hv.shape} and {c.shape}")
    if not (np.all(np.isfinite(hv)) and np.all(np.isfinite(c))):
        raise ValueError("h, cost: expected finite costs, got NaN or inf")
    out: NDArray[np.float64] = np.min(hv[:, None] + c, axis=0)
    return out


def trws_naive(
    mrf: PairwiseMRF,
    *,
    max_iter: int = 100,
    tol: float | None = 1e-9,
    order: ArrayLike | None = None,
) -> TRWSResult:
    """TRW-S in plain numpy with dense O(L_i * L_j) messages (the peer of :func:`trws`).

    Same schedule, weights, bound and decoding as :func:`trws`; grid costs are
    expanded to ``weight * min(D, gamma)`` with the grid's distance matrix D
    (built once per grid and metric). Results agree with :func:`trws` up to
    floating-point rounding.

    Parameters
    ----------
    mrf : PairwiseMRF
    max_iter, tol, order
        As in :func:`trws`.

    Returns
    -------
    TRWSResult
        ``backend == "naive"``.

    Examples
    --------
    >>> mrf = PairwiseMRF(np.array([[0.0, 1.0], [0.2, 0.0]]))
    >>> _ = mrf.add_dense_edge(0, 1, [[0.0, 1.0], [1.0, 0.0]])
    >>> trws_naive(mrf).labels.tolist()
    [0, 0]
    """
    n_iter, t, order_arr = _check_common(mrf, max_iter, tol, order)
    ar = mrf.as_arrays()
    n = ar.n_nodes
    n_e = ar.n_edges
    pos = np.empty(n, dtype=np.int64)
    pos[order_arr] = np.arange(n)
    unary = [ar.unary[ar.lab_off[i]: ar.lab_off[i + 1]] for i in range(n)]
    dist_cache: dict[tuple[int, int], NDArray[np.float64]] = {}

    def trunc_dist(e: int) -> NDArray[np.float64]:
        key = (int(ar.gid[e]), int(ar.kind[e]))
        if key not in dist_cache:
            dist_cache[key] = ar.grids[key[0]].distance_matrix("l1" if key[1] == 1 else "l2sq")
        return dist_cache[key]

    def cost(e: int) -> NDArray[np.float64]:
        if ar.kind[e] == 0:
            la = int(ar.lab_off[ar.ea[e] + 1] - ar.lab_off[ar.ea[e]])
            lb = int(ar.lab_off[ar.eb[e] + 1] - ar.lab_off[ar.eb[e]])
            return ar.costs[ar.cost_off[e]: ar.cost_off[e] + la * lb].reshape(la, lb)
        return ar.weight[e] * np.minimum(trunc_dist(e), ar.gamma[e])

    nbrs: list[list[tuple[int, int]]] = [[] for _ in range(n)]
    for e in range(n_e):
        a, b = int(ar.ea[e]), int(ar.eb[e])
        nbrs[a].append((e, b))
        nbrs[b].append((e, a))
    gnode = np.zeros(n)
    for i in range(n):
        n_fwd = sum(1 for _, j in nbrs[i] if pos[j] > pos[i])
        n_bwd = len(nbrs[i]) - n_fwd
        if nbrs[i]:
            gnode[i] = 1.0 / max(n_fwd, n_bwd)
    # into[e][0]: message into ea[e]; into[e][1]: message into eb[e]
    into = [[np.zeros(unary[int(ar.ea[e])].shape[0]), np.zeros(unary[int(ar.eb[e])].shape[0])] for e in range(n_e)]

    def side(e: int, i: int) -> int:
        return 0 if ar.ea[e] == i else 1

    def belief(i: int) -> NDArray[np.float64]:
        d = unary[i].copy()
        for e, _ in nbrs[i]:
            d += into[e][side(e, i)]
        return d

    def send(i: int, d: NDArray[np.float64], direction: int) -> float:
        total = 0.0
        for e, j in nbrs[i]:
            if (pos[j] - pos[i]) * direction <= 0:
                continue
            s = side(e, i)
            h = gnode[i] * d - into[e][s]
            c = cost(e)
            new = np.min(h[:, None] + c, axis=0) if s == 0 else np.min(h[None, :] + c, axis=1)
            vmin = float(new.min())
            into[e][1 - s] = new - vmin
            total += vmin
        return total

    lbs: list[float] = []
    es: list[float] = []
    best_e = math.inf
    best = np.zeros(n, dtype=np.int64)
    labels = np.zeros(n, dtype=np.int64)
    status = 0
    lb_prev = -math.inf
    for it in range(n_iter):
        for i in order_arr:
            send(int(i), belief(int(i)), 1)
        lb = 0.0
        for i in order_arr[::-1]:
            i = int(i)
            d = belief(i)
            vmin = float(d.min())
            lb += vmin + send(i, d - vmin, -1)
        e_val = 0.0
        for i in order_arr:
            i = int(i)
            dib = unary[i].copy()
            d = dib.copy()
            for e, j in nbrs[i]:
                if pos[j] < pos[i]:
                    c = cost(e)
                    dib += c[:, labels[j]] if side(e, i) == 0 else c[labels[j], :]
            d = dib.copy()
            for e, j in nbrs[i]:
                if pos[j] > pos[i]:
                    d += into[e][side(e, i)]
            labels[i] = int(np.argmin(d))
            e_val += float(dib[labels[i]])
        lbs.append(lb)
        es.append(e_val)
        if e_val < best_e:
            best_e = e_val
            best = labels.copy()
        if best_e - lb <= 1e-9 * max(1.0, abs(best_e)):
            status = 1
            break
        if t >= 0 and it > 0 and lb - lb_prev <= t * max(1.0, abs(lb)):
            status = 2
            break
        lb_prev = lb
    return _result(mrf, best, np.array(lbs), np.array(es), len(lbs), status, "naive")
