"""Generic pairwise Markov random fields over discrete labels.

A :class:`PairwiseMRF` holds one unary cost vector per node (each node may
have its own number of labels) and pairwise costs on undirected edges. An edge
cost is either a dense ``(L_i, L_j)`` matrix or a *structured* cost
``weight * min(dist(x_i, x_j), gamma)`` over a :class:`LabelGrid` (for the
pose CRF of the paper: yaw x pitch = 72 x 5 bins, yaw cyclic, truncation
``gamma`` = 20 degrees, weight = HOG distance of the two images). Structured
edges let :func:`posecrf.trws.trws` pass messages by distance transforms in
time linear in the number of labels instead of quadratic.

Convention: nodes are the integers ``0 .. N-1``; a labelling is an
``(N,) int`` array. Energies are costs (lower is better):
``E(x) = sum_i unary_i[x_i] + sum_(i,j) cost_ij(x_i, x_j)``. A dense edge cost
added as ``(i, j)`` is indexed ``cost[x_i, x_j]``. A label grid numbers its
labels in C order (``numpy.ravel_multi_index``), so for a yaw x pitch grid
``label = i_yaw * n_pitch + i_pitch``. Grid steps are metric (radians for
angles, as everywhere inside pano2cad); ``gamma`` is in the units of the
distance (radians for ``"l1"`` on angles, radians squared for ``"l2sq"``).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any, Literal

import numpy as np
from numpy.typing import ArrayLike, NDArray

__all__ = [
    "Metric",
    "LabelGrid",
    "GridCost",
    "PairwiseMRF",
    "MRFArrays",
    "energy",
    "knn_edges",
]

#: Distance on a label grid: ``"l1"`` = sum_a step_a * |d_a| (truncated linear),
#: ``"l2sq"`` = sum_a (step_a * d_a)**2 (truncated quadratic). On a cyclic axis
#: d_a is the shorter way round.
Metric = Literal["l1", "l2sq"]
_METRICS = ("l1", "l2sq")
_KIND = {"dense": 0, "l1": 1, "l2sq": 2}


def _finite_float(x: Any, name: str) -> float:
    try:
        v = float(x)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"{name}: expected a real number, got {x!r}") from exc
    if not math.isfinite(v):
        raise ValueError(f"{name}: expected a finite number, got {v}")
    return v


@dataclass(frozen=True)
class LabelGrid:
    """A regular grid of labels with metric steps, each axis optionally cyclic.

    Parameters
    ----------
    shape : tuple of int
        Number of bins per axis, e.g. ``(72, 5)`` for yaw x pitch.
    steps : tuple of float, optional
        Metric size of one bin per axis (default 1.0 each), e.g.
        ``(np.deg2rad(5), np.deg2rad(11.25))``.
    cyclic : tuple of bool, optional
        Whether the axis wraps (bin ``n-1`` is next to bin 0); default False.

    Convention: labels are numbered in C order over ``shape``.

    Examples
    --------
    >>> g = LabelGrid((4, 2), steps=(1.0, 0.5), cyclic=(True, False))
    >>> g.size, g.coords()[5].tolist()
    (8, [2, 1])
    >>> float(g.distance_matrix("l1")[0, 7])  # 1 step round the seam + 1 half step
    1.5
    """

    shape: tuple[int, ...]
    steps: tuple[float, ...] | None = None
    cyclic: tuple[bool, ...] | None = None

    def __post_init__(self) -> None:
        try:
            shape = tuple(int(n) for n in self.shape)
        except (TypeError, ValueError) as exc:
            raise ValueError(f"LabelGrid.shape: expected a tuple of positive ints, got {self.shape!r}") from exc
        if not shape or any(n < 1 for n in shape) or list(shape) != [n for n in self.shape]:
            raise ValueError(f"LabelGrid.shape: expected a non-empty tuple of positive ints, got {self.shape!r}")
        steps = (1.0,) * len(shape) if self.steps is None else tuple(self.steps)
        cyclic = (False,) * len(shape) if self.cyclic is None else tuple(self.cyclic)
        if len(steps) != len(shape) or len(cyclic) != len(shape):
            raise ValueError(
                f"LabelGrid: expected one step and one cyclic flag per axis ({len(shape)} axes), "
                f"got {len(steps)} steps and {len(cyclic)} flags"
            )
        fsteps = tuple(_finite_float(s, "LabelGrid.steps") for s in steps)
        if any(s <= 0 for s in fsteps):
            raise ValueError(f"LabelGrid.steps: expected positive steps, got {fsteps}")
        object.__setattr__(self, "shape", shape)
        object.__setattr__(self, "steps", fsteps)
        object.__setattr__(self, "cyclic", tuple(bool(c) for c in cyclic))

    @property
    def size(self) -> int:
        """Number of labels L = prod(shape)."""
        return int(np.prod(self.shape))

    @property
    def ndim(self) -> int:
        """Number of grid axes."""
        return len(self.shape)

    def coords(self) -> NDArray[np.int64]:
        """Grid coordinates of every label: ``(L, ndim) int``, row ``x`` = unravel(x)."""
        return np.stack(np.unravel_index(np.arange(self.size), self.shape), axis=1).astype(np.int64)

    def distance(self, x: ArrayLike, y: ArrayLike, metric: Metric = "l1") -> NDArray[np.float64]:
        """Distance between labels ``x`` and ``y`` (broadcast), in the grid's metric units.

        Parameters
        ----------
        x, y : (...) int
            Label indices in ``[0, L)``.
        metric : {"l1", "l2sq"}

        Returns
        -------
        dist : (...) float
        """
        if metric not in _METRICS:
            raise ValueError(f"metric: expected one of {_METRICS}, got {metric!r}")
        xa = np.asarray(x)
        ya = np.asarray(y)
        for name, a in (("x", xa), ("y", ya)):
            if a.size and (not np.issubdtype(a.dtype, np.integer) or a.min() < 0 or a.max() >= self.size):
                raise ValueError(f"{name}: expected integer labels in [0, {self.size}), got {a.dtype} values")
        cx = np.unravel_index(xa.astype(np.int64), self.shape)
        cy = np.unravel_index(ya.astype(np.int64), self.shape)
        dist: NDArray[np.float64] = np.zeros(np.broadcast(xa, ya).shape, dtype=np.float64)
        for ax, (n, step, cyc) in enumerate(zip(self.shape, self.steps, self.cyclic)):
            delta = np.abs(cx[ax] - cy[ax])
            if cyc:
                delta = np.minimum(delta, n - delta)
            if metric == "l1":
                dist = dist + step * delta
            else:
                t = step * delta
                dist = dist + t * t
        return dist

    def distance_matrix(self, metric: Metric = "l1") -> NDArray[np.float64]:
        """All pairwise label distances: ``(L, L) float``."""
        lab = np.arange(self.size)
        return self.distance(lab[:, None], lab[None, :], metric)


@dataclass(frozen=True)
class GridCost:
    """Structured pairwise cost ``weight * min(dist(x_i, x_j), gamma)`` on a label grid.

    Parameters
    ----------
    grid : LabelGrid
    weight : float
        Non-negative multiplier (the paper uses the HOG distance of the two images).
    gamma : float
        Non-negative truncation threshold in distance units; ``inf`` = no truncation.
    metric : {"l1", "l2sq"}

    Examples
    --------
    >>> c = GridCost(LabelGrid((4,), cyclic=(True,)), weight=2.0, gamma=1.5)
    >>> c.dense()[0].tolist()
    [0.0, 2.0, 3.0, 2.0]
    """

    grid: LabelGrid
    weight: float
    gamma: float = math.inf
    metric: Metric = "l1"

    def __post_init__(self) -> None:
        if not isinstance(self.grid, LabelGrid):
            raise ValueError(f"GridCost.grid: expected a LabelGrid, got {type(self.grid).__name__}")
        w = _finite_float(self.weight, "GridCost.weight")
        if w < 0:
            raise ValueError(f"GridCost.weight: expected weight >= 0, got {w}")
        try:
            g = float(self.gamma)
        except (TypeError, ValueError) as exc:
            raise ValueError(f"GridCost.gamma: expected a real number, got {self.gamma!r}") from exc
        if math.isnan(g) or g < 0:
            raise ValueError(f"GridCost.gamma: expected gamma >= 0 (inf for no truncation), got {g}")
        if self.metric not in _METRICS:
            raise ValueError(f"GridCost.metric: expected one of {_METRICS}, got {self.metric!r}")
        object.__setattr__(self, "weight", w)
        object.__setattr__(self, "gamma", g)

    def dense(self) -> NDArray[np.float64]:
        """The same cost as a dense ``(L, L) float`` matrix."""
        return self.weight * np.minimum(self.grid.distance_matrix(self.metric), self.gamma)


@dataclass(frozen=True)
class MRFArrays:
    """Flat array form of a :class:`PairwiseMRF`, as the solvers read it.

    Attributes
    ----------
    lab_off : (N+1,) int
        Node i's labels are ``unary[lab_off[i]:lab_off[i+1]]``.
    unary : (sum L_i,) float
    ea, eb : (E,) int
        Edge endpoints as added; dense costs are indexed ``[x_ea, x_eb]``.
    kind : (E,) int
        0 dense, 1 grid "l1", 2 grid "l2sq".
    cost_off : (E,) int
        Offset of a dense edge's row-major matrix in ``costs`` (-1 for grid edges).
    costs : (C,) float
    gid, weight, gamma : (E,) int, (E,) float, (E,) float
        Grid index (-1 for dense edges), weight and truncation of grid edges.
    grids : tuple of LabelGrid
    g_ndim : (G,) int ; g_shape, g_step, g_cyc : (G, D) int / float / int
        The grids' axes, padded to the largest number of axes D.
    """

    lab_off: NDArray[np.int64]
    unary: NDArray[np.float64]
    ea: NDArray[np.int64]
    eb: NDArray[np.int64]
    kind: NDArray[np.int64]
    cost_off: NDArray[np.int64]
    costs: NDArray[np.float64]
    gid: NDArray[np.int64]
    weight: NDArray[np.float64]
    gamma: NDArray[np.float64]
    grids: tuple[LabelGrid, ...]
    g_ndim: NDArray[np.int64]
    g_shape: NDArray[np.int64]
    g_step: NDArray[np.float64]
    g_cyc: NDArray[np.int64]

    @property
    def n_nodes(self) -> int:
        return int(self.lab_off.shape[0] - 1)

    @property
    def n_edges(self) -> int:
        return int(self.ea.shape[0])


@dataclass
class _EdgeStore:
    ea: list[int] = field(default_factory=list)
    eb: list[int] = field(default_factory=list)
    kind: list[int] = field(default_factory=list)
    dense: list[NDArray[np.float64] | None] = field(default_factory=list)
    gid: list[int] = field(default_factory=list)
    weight: list[float] = field(default_factory=list)
    gamma: list[float] = field(default_factory=list)


class PairwiseMRF:
    """A pairwise MRF: unary costs per node and dense or grid-structured edge costs.

    Parameters
    ----------
    unaries : (N, L) float or sequence of (L_i,) float
        Unary cost of each label of each node (finite). Nodes may have
        different label counts when given as a sequence.

    Convention: see the module docstring (nodes ``0..N-1``, costs, C-order
    grid labels). Edges are undirected; at most one edge per node pair, no
    self-loops.

    Examples
    --------
    >>> mrf = PairwiseMRF([[0.0, 1.0], [1.0, 0.0, 2.0]])
    >>> mrf.add_dense_edge(0, 1, [[0.0, 5.0, 5.0], [5.0, 0.0, 5.0]])
    0
    >>> mrf.n_nodes, mrf.n_labels.tolist(), mrf.edges.tolist()
    (2, [2, 3], [[0, 1]])
    >>> energy(mrf, [1, 1])
    1.0
    """

    def __init__(self, unaries: ArrayLike | Sequence[ArrayLike]) -> None:
        rows: list[NDArray[np.float64]]
        if isinstance(unaries, np.ndarray):
            if unaries.ndim != 2:
                raise ValueError(
                    f"unaries: expected an (N, L) array or a sequence of (L_i,) arrays, got shape {unaries.shape}"
                )
            rows = [np.asarray(u) for u in unaries]
        else:
            try:
                rows = [np.asarray(u) for u in unaries]  # type: ignore[union-attr]
            except TypeError as exc:
                raise ValueError(
                    "unaries: expected an (N, L) array or a sequence of (L_i,) arrays, "
                    f"got {type(unaries).__name__}"
                ) from exc
        if not rows:
            raise ValueError("unaries: expected at least one node, got 0")
        self._unaries: list[NDArray[np.float64]] = []
        for i, u in enumerate(rows):
            if u.ndim != 1 or u.shape[0] < 1:
                raise ValueError(f"unaries[{i}]: expected a non-empty 1-D cost vector (L_i,), got shape {u.shape}")
            try:
                uf = np.array(u, dtype=np.float64)
            except (TypeError, ValueError) as exc:
                raise ValueError(f"unaries[{i}]: expected numeric costs, got dtype {u.dtype}") from exc
            if not np.all(np.isfinite(uf)):
                raise ValueError(f"unaries[{i}]: expected finite costs, got NaN or inf")
            uf.setflags(write=False)
            self._unaries.append(uf)
        self._n_labels = np.array([u.shape[0] for u in self._unaries], dtype=np.int64)
        self._e = _EdgeStore()
        self._pairs: dict[tuple[int, int], int] = {}
        self._grids: dict[LabelGrid, int] = {}
        self._arrays: MRFArrays | None = None

    # ------------------------------------------------------------------ queries
    @property
    def n_nodes(self) -> int:
        """Number of nodes N."""
        return len(self._unaries)

    @property
    def n_edges(self) -> int:
        """Number of edges E."""
        return len(self._e.ea)

    @property
    def n_labels(self) -> NDArray[np.int64]:
        """Label count of each node: ``(N,) int``."""
        return self._n_labels.copy()

    @property
    def edges(self) -> NDArray[np.int64]:
        """Edge endpoints in insertion order: ``(E, 2) int``."""
        return np.array([self._e.ea, self._e.eb], dtype=np.int64).reshape(2, -1).T.copy()

    def unary(self, i: int) -> NDArray[np.float64]:
        """Unary costs of node ``i``: ``(L_i,) float`` (read-only view)."""
        return self._unaries[self._node(i, "i")]

    def edge_cost(self, e: int) -> NDArray[np.float64]:
        """Dense ``(L_a, L_b) float`` cost of edge ``e`` = (a, b) (grid costs are expanded)."""
        if not (0 <= int(e) < self.n_edges):
            raise ValueError(f"e: expected an edge index in [0, {self.n_edges}), got {e}")
        e = int(e)
        dense = self._e.dense[e]
        if dense is not None:
            return dense.copy()
        grid = self.grids[self._e.gid[e]]
        metric: Metric = "l1" if self._e.kind[e] == _KIND["l1"] else "l2sq"
        return GridCost(grid, self._e.weight[e], self._e.gamma[e], metric).dense()

    @property
    def grids(self) -> tuple[LabelGrid, ...]:
        """The distinct label grids used by grid edges, in first-use order."""
        return tuple(self._grids)

    # ------------------------------------------------------------------ building
    def _node(self, i: Any, name: str) -> int:
        try:
            ii = int(i)
        except (TypeError, ValueError) as exc:
            raise ValueError(f"{name}: expected a node index, got {i!r}") from exc
        if ii != i or not (0 <= ii < self.n_nodes):
            raise ValueError(
                f"{name}: expected a node index in [0, {self.n_nodes}), got {i!r} (edge to a missing node)"
            )
        return ii

    def _check_pair(self, i: Any, j: Any) -> tuple[int, int]:
        a, b = self._node(i, "i"), self._node(j, "j")
        if a == b:
            raise ValueError(f"edge ({a}, {b}): expected two different nodes, got a self-loop")
        key = (min(a, b), max(a, b))
        if key in self._pairs:
            raise ValueError(
                f"edge ({a}, {b}): expected at most one edge per node pair, "
                f"edge {self._pairs[key]} exists (add the costs instead)"
            )
        return a, b

    def _append(
        self, a: int, b: int, kind: int, dense: NDArray[np.float64] | None, gid: int, w: float, g: float
    ) -> int:
        e = self.n_edges
        self._pairs[(min(a, b), max(a, b))] = e
        st = self._e
        st.ea.append(a)
        st.eb.append(b)
        st.kind.append(kind)
        st.dense.append(dense)
        st.gid.append(gid)
        st.weight.append(w)
        st.gamma.append(g)
        self._arrays = None
        return e

    def add_dense_edge(self, i: int, j: int, cost: ArrayLike) -> int:
        """Add edge (i, j) with a dense cost ``cost[x_i, x_j]``: ``(L_i, L_j) float``, finite.

        Returns the edge index.
        """
        a, b = self._check_pair(i, j)
        c = np.asarray(cost)
        want = (int(self._n_labels[a]), int(self._n_labels[b]))
        if c.shape != want:
            raise ValueError(f"cost of edge ({a}, {b}): expected shape (L_i, L_j) = {want}, got {c.shape}")
        try:
            cf = np.array(c, dtype=np.float64)
        except (TypeError, ValueError) as exc:
            raise ValueError(f"cost of edge ({a}, {b}): expected numeric costs, got dtype {c.dtype}") from exc
        if not np.all(np.isfinite(cf)):
            raise ValueError(f"cost of edge ({a}, {b}): expected finite costs, got NaN or inf")
        cf.setflags(write=False)
        return self._append(a, b, _KIND["dense"], cf, -1, 0.0, 0.0)

    def _grid_id(self, grid: LabelGrid) -> int:
        if grid not in self._grids:
            self._grids[grid] = len(self._grids)
        return self._grids[grid]

    def add_grid_edge(self, i: int, j: int, cost: GridCost) -> int:
        """Add edge (i, j) with a structured :class:`GridCost`; both nodes need ``grid.size`` labels.

        Returns the edge index.
        """
        if not isinstance(cost, GridCost):
            raise ValueError(f"cost: expected a GridCost, got {type(cost).__name__}")
        a, b = self._check_pair(i, j)
        L = cost.grid.size
        if self._n_labels[a] != L or self._n_labels[b] != L:
            raise ValueError(
                f"edge ({a}, {b}): expected both nodes to have grid.size = {L} labels, "
                f"got {int(self._n_labels[a])} and {int(self._n_labels[b])}"
            )
        return self._append(a, b, _KIND[cost.metric], None, self._grid_id(cost.grid), cost.weight, cost.gamma)

    def add_grid_edges(
        self,
        pairs: ArrayLike,
        grid: LabelGrid,
        weights: ArrayLike,
        gamma: float = math.inf,
        metric: Metric = "l1",
    ) -> NDArray[np.int64]:
        """Add many grid edges at once: cost ``weights[k] * min(dist, gamma)`` on ``pairs[k]``.

        Parameters
        ----------
        pairs : (E, 2) int
        grid : LabelGrid
        weights : (E,) float or float
            Non-negative finite weights (a scalar applies to all).
        gamma : float
            Non-negative truncation (inf = none).
        metric : {"l1", "l2sq"}

        Returns
        -------
        edge_ids : (E,) int
        """
        p = np.asarray(pairs)
        if p.ndim != 2 or p.shape[1] != 2 or (p.size and not np.issubdtype(p.dtype, np.integer)):
            raise ValueError(f"pairs: expected an (E, 2) integer array, got shape {p.shape} dtype {p.dtype}")
        w = np.broadcast_to(np.asarray(weights, dtype=np.float64), (p.shape[0],))
        GridCost(grid, 0.0, gamma, metric)  # validates grid, gamma, metric
        if not np.all(np.isfinite(w)) or np.any(w < 0):
            raise ValueError("weights: expected finite weights >= 0, got negative, NaN or inf values")
        ids = np.empty(p.shape[0], dtype=np.int64)
        for k in range(p.shape[0]):
            ids[k] = self.add_grid_edge(int(p[k, 0]), int(p[k, 1]), GridCost(grid, float(w[k]), gamma, metric))
        return ids

    @classmethod
    def from_networkx(cls, graph: Any, unary: str = "unary", cost: str = "cost", rows: str = "rows") -> PairwiseMRF:
        """Build an MRF from a ``networkx.Graph``.

        Parameters
        ----------
        graph : networkx.Graph
            Node ``k`` of ``list(graph.nodes)`` becomes MRF node ``k``. Every
            node carries its unary cost vector under attribute ``unary``; every
            edge carries under ``cost`` either a :class:`GridCost` or a dense
            matrix. A dense matrix's rows index the labels of the node named by
            the edge attribute ``rows`` (may be omitted for a symmetric matrix).
        unary, cost, rows : str
            Attribute names.

        Returns
        -------
        PairwiseMRF

        Examples
        --------
        >>> import networkx as nx
        >>> g = nx.Graph()
        >>> g.add_node("a", unary=[0.0, 2.0]); g.add_node("b", unary=[1.0, 0.0])
        >>> g.add_edge("a", "b", cost=[[0.0, 3.0], [3.0, 0.0]])
        >>> PairwiseMRF.from_networkx(g).edges.tolist()
        [[0, 1]]
        """
        try:
            nodes = list(graph.nodes)
            node_data = graph.nodes
            edge_iter = list(graph.edges(data=True))
        except AttributeError as exc:
            raise ValueError(f"graph: expected a networkx.Graph, got {type(graph).__name__}") from exc
        if graph.is_directed() or graph.is_multigraph():
            raise ValueError(
                "graph: expected an undirected simple networkx.Graph, got a directed graph or a multigraph"
            )
        index = {n: k for k, n in enumerate(nodes)}
        un = []
        for n in nodes:
            if unary not in node_data[n]:
                raise ValueError(f"node {n!r}: expected a unary cost vector under attribute {unary!r}")
            un.append(np.asarray(node_data[n][unary]))
        mrf = cls(un)
        for u, v, data in edge_iter:
            if cost not in data:
                raise ValueError(f"edge ({u!r}, {v!r}): expected a cost under attribute {cost!r}")
            c = data[cost]
            if isinstance(c, GridCost):
                mrf.add_grid_edge(index[u], index[v], c)
                continue
            m = np.asarray(c)
            r = data.get(rows)
            if r is None:
                if m.ndim != 2 or m.shape[0] != m.shape[1] or not np.array_equal(m, m.T):
                    raise ValueError(
                        f"edge ({u!r}, {v!r}): a non-symmetric dense cost needs the edge attribute {rows!r} "
                        f"naming the node whose labels index its rows"
                    )
                r = u
            if r not in (u, v):
                raise ValueError(f"edge ({u!r}, {v!r}): attribute {rows!r} must name one of its nodes, got {r!r}")
            other = v if r == u else u
            mrf.add_dense_edge(index[r], index[other], m)
        return mrf

    # ------------------------------------------------------------------ arrays
    def as_arrays(self) -> MRFArrays:
        """The flat array form read by the solvers (cached until the MRF changes)."""
        if self._arrays is not None:
            return self._arrays
        st = self._e
        n_e = self.n_edges
        lab_off = np.zeros(self.n_nodes + 1, dtype=np.int64)
        np.cumsum(self._n_labels, out=lab_off[1:])
        unary = np.concatenate(self._unaries).astype(np.float64)
        cost_off = np.full(n_e, -1, dtype=np.int64)
        chunks = []
        off = 0
        for e, d in enumerate(st.dense):
            if d is not None:
                cost_off[e] = off
                chunks.append(d.ravel())
                off += d.size
        costs = np.concatenate(chunks) if chunks else np.zeros(1, dtype=np.float64)
        grids = self.grids
        dmax = max((g.ndim for g in grids), default=1)
        n_g = max(len(grids), 1)
        g_ndim = np.zeros(n_g, dtype=np.int64)
        g_shape = np.ones((n_g, dmax), dtype=np.int64)
        g_step = np.ones((n_g, dmax), dtype=np.float64)
        g_cyc = np.zeros((n_g, dmax), dtype=np.int64)
        for k, g in enumerate(grids):
            g_ndim[k] = g.ndim
            g_shape[k, : g.ndim] = g.shape
            g_step[k, : g.ndim] = g.steps
            g_cyc[k, : g.ndim] = g.cyclic
        arrays = MRFArrays(
            lab_off=lab_off,
            unary=unary,
            ea=np.array(st.ea, dtype=np.int64),
            eb=np.array(st.eb, dtype=np.int64),
            kind=np.array(st.kind, dtype=np.int64),
            cost_off=cost_off,
            costs=costs.astype(np.float64),
            gid=np.array(st.gid, dtype=np.int64),
            weight=np.array(st.weight, dtype=np.float64),
            gamma=np.array(st.gamma, dtype=np.float64),
            grids=grids,
            g_ndim=g_ndim,
            g_shape=g_shape,
            g_step=g_step,
            g_cyc=g_cyc,
        )
        for a in (arrays.lab_off, arrays.unary, arrays.ea, arrays.eb, arrays.kind, arrays.cost_off, arrays.costs,
                  arrays.gid, arrays.weight, arrays.gamma, arrays.g_ndim, arrays.g_shape, arrays.g_step, arrays.g_cyc):
            a.setflags(write=False)
        self._arrays = arrays
        return arrays

    def __repr__(self) -> str:
        return f"PairwiseMRF(n_nodes={self.n_nodes}, n_edges={self.n_edges}, max_labels={int(self._n_labels.max())})"


def check_labels(mrf: PairwiseMRF, labels: ArrayLike) -> NDArray[np.int64]:
    """Validate a labelling: ``(N,) int`` with ``0 <= labels[i] < L_i``."""
    lab = np.asarray(labels)
    if lab.shape != (mrf.n_nodes,):
        raise ValueError(f"labels: expected shape (N,) = ({mrf.n_nodes},), got {lab.shape}")
    if lab.size and not np.issubdtype(lab.dtype, np.integer):
        raise ValueError(f"labels: expected integer labels, got dtype {lab.dtype}")
    lab = lab.astype(np.int64)
    bad = np.flatnonzero((lab < 0) | (lab >= mrf._n_labels))
    if bad.size:
        k = int(bad[0])
        raise ValueError(f"labels[{k}]: expected a label in [0, {int(mrf._n_labels[k])}), got {int(lab[k])}")
    return lab


def energy(mrf: PairwiseMRF, labels: ArrayLike) -> float:
    """Energy ``E(x) = sum_i unary_i[x_i] + sum_(i,j) cost_ij(x_i, x_j)`` of a labelling.

    Parameters
    ----------
    mrf : PairwiseMRF
    labels : (N,) int

    Returns
    -------
    float

    Convention: costs, lower is better; dense edge costs indexed ``[x_i, x_j]``
    for an edge added as ``(i, j)``.

    Examples
    --------
    >>> mrf = PairwiseMRF(np.array([[0.0, 1.0], [1.0, 0.0]]))
    >>> _ = mrf.add_grid_edge(0, 1, GridCost(LabelGrid((2,)), weight=3.0))
    >>> energy(mrf, [0, 1]), energy(mrf, [0, 0])
    (3.0, 1.0)
    """
    if not isinstance(mrf, PairwiseMRF):
        raise ValueError(f"mrf: expected a PairwiseMRF, got {type(mrf).__name__}")
    lab = check_labels(mrf, labels)
    ar = mrf.as_arrays()
    total = float(np.sum(ar.unary[ar.lab_off[:-1] + lab]))
    if ar.n_edges == 0:
        return total
    xa = lab[ar.ea]
    xb = lab[ar.eb]
    pair = np.zeros(ar.n_edges, dtype=np.float64)
    dense = np.flatnonzero(ar.kind == _KIND["dense"])
    if dense.size:
        nb = mrf._n_labels[ar.eb[dense]]
        pair[dense] = ar.costs[ar.cost_off[dense] + xa[dense] * nb + xb[dense]]
    for g_idx, grid in enumerate(ar.grids):
        for metric in _METRICS:
            sel = np.flatnonzero((ar.gid == g_idx) & (ar.kind == _KIND[metric]))
            if sel.size:
                d = grid.distance(xa[sel], xb[sel], metric)
                pair[sel] = ar.weight[sel] * np.minimum(d, ar.gamma[sel])
    return total + float(np.sum(pair))


def knn_edges(points: ArrayLike, k: int) -> NDArray[np.int64]:
    """Undirected k-nearest-neighbour graph: each point linked to its ``k`` nearest others.

    Parameters
    ----------
    points : (N, D) float
    k : int
        1 <= k < N.

    Returns
    -------
    edges : (E, 2) int
        Unique pairs ``i < j``, sorted; ``E <= N*k`` (mutual neighbours count once).

    Examples
    --------
    >>> knn_edges([[0.0], [1.0], [3.0], [7.0]], 1).tolist()
    [[0, 1], [1, 2], [2, 3]]
    """
    pts = np.asarray(points, dtype=np.float64)
    if pts.ndim != 2 or pts.shape[0] < 2:
        raise ValueError(f"points: expected an (N, D) array with N >= 2, got shape {pts.shape}")
    if not np.all(np.isfinite(pts)):
        raise ValueError("points: expected finite coordinates, got NaN or inf")
    if int(k) != k or not (1 <= k < pts.shape[0]):
        raise ValueError(f"k: expected an integer in [1, N) = [1, {pts.shape[0]}), got {k!r}")
    from scipy.spatial import cKDTree

    _, idx = cKDTree(pts).query(pts, k=int(k) + 1)
    n = pts.shape[0]
    src = np.repeat(np.arange(n), int(k))
    dst = np.empty(n * int(k), dtype=np.int64)
    # drop each point itself (it may not be in column 0 when points coincide)
    for i in range(n):
        row = [j for j in idx[i] if j != i][: int(k)]
        dst[i * int(k) : (i + 1) * int(k)] = row
    a = np.minimum(src, dst)
    b = np.maximum(src, dst)
    return np.unique(np.stack([a, b], axis=1), axis=0).astype(np.int64)
