"""Tests of posecrf.mrf (pairwise MRF) and posecrf.trws (TRW-S solver).

Peers: brute force on small MRFs, exact dynamic programming on chains and
trees, dense O(L^2) messages for the distance-transform messages, the plain
numpy TRW-S (trws_naive) and the uncompiled kernels (backend="python").
"""

from __future__ import annotations

import itertools
import math

import networkx as nx
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from posecrf.mrf import GridCost, LabelGrid, PairwiseMRF, energy, knn_edges
from posecrf.trws import dense_message, grid_message, trws, trws_naive

# ----------------------------------------------------------------------------- helpers


def random_grid_cost(rng: np.random.Generator, n_labels: int) -> GridCost:
    shape = (2, 2) if n_labels == 4 and rng.random() < 0.5 else (n_labels,)
    grid = LabelGrid(
        shape,
        steps=tuple(float(s) for s in rng.uniform(0.5, 2.0, len(shape))),
        cyclic=tuple(bool(c) for c in rng.random(len(shape)) < 0.5),
    )
    gamma = math.inf if rng.random() < 0.25 else float(rng.uniform(0.5, 3.0))
    metric = "l1" if rng.random() < 0.6 else "l2sq"
    return GridCost(grid, weight=float(rng.uniform(0.0, 2.0)), gamma=gamma, metric=metric)


def add_random_edge(
    mrf: PairwiseMRF, rng: np.random.Generator, i: int, j: int, dense_range: tuple[float, float] = (0.0, 1.0)
) -> None:
    li, lj = int(mrf.n_labels[i]), int(mrf.n_labels[j])
    if li == lj and rng.random() < 0.5:
        mrf.add_grid_edge(i, j, random_grid_cost(rng, li))
    else:
        mrf.add_dense_edge(i, j, rng.uniform(*dense_range, (li, lj)))


def random_loopy_mrf(rng: np.random.Generator, dense_range: tuple[float, float] = (0.0, 1.0)) -> PairwiseMRF:
    """3-6 nodes, 2-4 labels each, a cycle through all nodes plus random chords.

    Unaries uniform in [0, 2]; dense pairwise costs uniform in ``dense_range``
    (random, hence frustrated); grid costs with weights in [0, 2].
    """
    n = int(rng.integers(3, 7))
    mrf = PairwiseMRF([rng.uniform(0.0, 2.0, int(rng.integers(2, 5))) for _ in range(n)])
    perm = rng.permutation(n)
    pairs = {tuple(sorted((int(perm[k]), int(perm[(k + 1) % n])))) for k in range(n)}
    for a, b in itertools.combinations(range(n), 2):
        if rng.random() < 0.3:
            pairs.add((a, b))
    for a, b in sorted(pairs):
        if rng.random() < 0.5:
            a, b = b, a
        add_random_edge(mrf, rng, a, b, dense_range)
    return mrf


def random_tree_mrf(rng: np.random.Generator, chain: bool) -> PairwiseMRF:
    n = int(rng.integers(2, 13))
    mrf = PairwiseMRF([rng.uniform(0.0, 2.0, int(rng.integers(2, 6))) for _ in range(n)])
    for k in range(1, n):
        parent = k - 1 if chain else int(rng.integers(0, k))
        a, b = (parent, k) if rng.random() < 0.5 else (k, parent)
        add_random_edge(mrf, rng, a, b)
    return mrf


def brute_force(mrf: PairwiseMRF) -> tuple[float, np.ndarray]:
    """Minimum energy over all labellings, from the dense edge costs."""
    ranges = [range(int(n)) for n in mrf.n_labels]
    lab = np.array(list(itertools.product(*ranges)), dtype=np.int64)
    e = np.zeros(lab.shape[0])
    for i in range(mrf.n_nodes):
        e += mrf.unary(i)[lab[:, i]]
    for k, (a, b) in enumerate(mrf.edges):
        e += mrf.edge_cost(k)[lab[:, a], lab[:, b]]
    best = int(np.argmin(e))
    return float(e[best]), lab[best]


def tree_dp(mrf: PairwiseMRF) -> float:
    """Exact minimum on a forest by min-sum dynamic programming from the leaves."""
    nbrs: dict[int, list[tuple[int, np.ndarray]]] = {i: [] for i in range(mrf.n_nodes)}
    for k, (a, b) in enumerate(mrf.edges):
        c = mrf.edge_cost(k)
        nbrs[int(a)].append((int(b), c))      # cost[x_a, x_b]
        nbrs[int(b)].append((int(a), c.T))    # cost[x_b, x_a]
    seen: set[int] = set()

    def up(i: int, parent: int) -> np.ndarray:
        seen.add(i)
        total = mrf.unary(i).copy()
        for j, c in nbrs[i]:
            if j != parent:
                total += np.min(up(j, i)[None, :] + c, axis=1)
        return total

    result = 0.0
    for r in range(mrf.n_nodes):
        if r not in seen:
            result += float(up(r, -1).min())
    return result


# ----------------------------------------------------------------------------- TRW-S vs exact


def optimal_rate(seed: int, dense_range: tuple[float, float], n_cases: int = 200) -> float:
    rng = np.random.default_rng(seed)
    n_opt = 0
    for _ in range(n_cases):
        mrf = random_loopy_mrf(rng, dense_range)
        opt, _ = brute_force(mrf)
        res = trws(mrf, max_iter=100)
        assert res.lower_bound <= opt + 1e-9
        assert res.energy >= opt - 1e-9
        assert np.isclose(res.energy, energy(mrf, res.labels))
        # the bound never decreases from one iteration to the next
        assert np.all(np.diff(res.lower_bounds) >= -1e-9 * max(1.0, abs(opt)))
        n_opt += bool(res.energy <= opt + 1e-9)
    return n_opt / n_cases


def test_trws_matches_brute_force_on_random_loopy_mrfs() -> None:
    rate = optimal_rate(8, (0.0, 1.0))
    assert rate >= 0.95, f"optimal in {rate:.1%} of the cases"


def test_trws_on_strongly_frustrated_mrfs() -> None:
    # dense costs as strong as the unaries and partly negative: the LP relaxation
    # is often not tight, the bound stays below the optimum, decoding still mostly hits it
    rate = optimal_rate(9, (-0.5, 2.0))
    assert rate >= 0.90, f"optimal in {rate:.1%} of the cases"


@pytest.mark.parametrize("chain", [True, False])
def test_trws_exact_on_chains_and_trees(chain: bool) -> None:
    rng = np.random.default_rng(3 if chain else 4)
    for _ in range(60):
        mrf = random_tree_mrf(rng, chain)
        order = rng.permutation(mrf.n_nodes)
        res = trws(mrf, order=order, max_iter=200)
        opt = tree_dp(mrf)
        assert res.energy == pytest.approx(opt, abs=1e-9)
        assert res.lower_bound <= opt + 1e-9


def test_chain_in_order_needs_one_iteration() -> None:
    rng = np.random.default_rng(5)
    mrf = random_tree_mrf(rng, chain=True)
    while mrf.n_nodes < 5:
        mrf = random_tree_mrf(rng, chain=True)
    res = trws(mrf)
    assert res.iterations == 1 and res.converged
    assert res.reason.startswith("duality gap closed")
    assert res.lower_bound == pytest.approx(tree_dp(mrf), abs=1e-9)


# ----------------------------------------------------------------------------- messages


@st.composite
def grid_costs(draw: st.DrawFn) -> GridCost:
    ndim = draw(st.integers(1, 3))
    shape = tuple(draw(st.integers(1, 7)) for _ in range(ndim))
    steps = tuple(draw(st.floats(0.05, 3.0)) for _ in range(ndim))
    cyclic = tuple(draw(st.booleans()) for _ in range(ndim))
    gamma = draw(st.one_of(st.just(math.inf), st.floats(0.0, 10.0)))
    weight = draw(st.floats(0.0, 5.0))
    metric = draw(st.sampled_from(["l1", "l2sq"]))
    return GridCost(LabelGrid(shape, steps, cyclic), weight=weight, gamma=gamma, metric=metric)


@settings(max_examples=300, deadline=None)
@given(cost=grid_costs(), seed=st.integers(0, 2**32 - 1), scale=st.floats(0.01, 100.0))
def test_grid_message_equals_dense_message(cost: GridCost, seed: int, scale: float) -> None:
    h = np.random.default_rng(seed).uniform(-1.0, 1.0, cost.grid.size) * scale
    fast = grid_message(h, cost)
    ref = dense_message(h, cost.dense())
    np.testing.assert_allclose(fast, ref, rtol=1e-12, atol=1e-9 * max(1.0, scale))


def test_grid_message_pose_grid_example() -> None:
    # the paper's pose grid: 72 yaw bins x 5 pitch bins, yaw cyclic, gamma = 20 deg
    grid = LabelGrid((72, 5), (np.deg2rad(5.0), np.deg2rad(11.25)), (True, False))
    cost = GridCost(grid, weight=0.7, gamma=np.deg2rad(20.0))
    h = np.random.default_rng(0).uniform(0, 1, 360)
    np.testing.assert_allclose(grid_message(h, cost), dense_message(h, cost.dense()), rtol=0, atol=1e-12)
    # yaw bin 71 is next to bin 0 (5 deg), pitch bins are 11.25 deg apart
    assert grid.distance(0, 71 * 5) == pytest.approx(np.deg2rad(5.0))
    assert grid.distance(0, 1) == pytest.approx(np.deg2rad(11.25))


def test_label_grid_distance_against_loops() -> None:
    grid = LabelGrid((5, 3, 2), (0.5, 1.5, 2.0), (True, False, True))
    d1 = grid.distance_matrix("l1")
    d2 = grid.distance_matrix("l2sq")
    coords = list(itertools.product(range(5), range(3), range(2)))
    for x, cx in enumerate(coords):
        for y, cy in enumerate(coords):
            deltas = []
            for a, (n, cyc) in enumerate(zip(grid.shape, grid.cyclic)):
                dd = abs(cx[a] - cy[a])
                deltas.append(min(dd, n - dd) if cyc else dd)
            assert d1[x, y] == pytest.approx(sum(s * dd for s, dd in zip(grid.steps, deltas)))
            assert d2[x, y] == pytest.approx(sum((s * dd) ** 2 for s, dd in zip(grid.steps, deltas)))


# ----------------------------------------------------------------------------- peers and backends


def pose_like_mrf(seed: int, n: int = 40, k: int = 4, shape: tuple[int, int] = (24, 3)) -> PairwiseMRF:
    rng = np.random.default_rng(seed)
    grid = LabelGrid(shape, (2 * np.pi / shape[0], np.deg2rad(15.0)), (True, False))
    mrf = PairwiseMRF(rng.uniform(0.0, 1.0, (n, grid.size)))
    pairs = knn_edges(rng.uniform(0, 1, (n, 2)), k)
    mrf.add_grid_edges(pairs, grid, rng.uniform(0.1, 1.0, len(pairs)), gamma=np.deg2rad(40.0))
    return mrf


def test_trws_agrees_with_naive_peer() -> None:
    for seed in range(3):
        mrf = pose_like_mrf(seed)
        fast = trws(mrf, max_iter=15, tol=None)
        slow = trws_naive(mrf, max_iter=15, tol=None)
        np.testing.assert_allclose(fast.lower_bounds, slow.lower_bounds, rtol=1e-10, atol=1e-10)
        np.testing.assert_allclose(fast.energies, slow.energies, rtol=1e-10, atol=1e-10)
        assert fast.energy == pytest.approx(slow.energy, abs=1e-9)


def test_python_backend_gives_identical_results() -> None:
    rng = np.random.default_rng(11)
    for _ in range(4):
        mrf = random_loopy_mrf(rng)
        a = trws(mrf, max_iter=20, tol=None)
        b = trws(mrf, max_iter=20, tol=None, backend="python")
        assert a.labels.tolist() == b.labels.tolist()
        assert a.lower_bounds.tolist() == b.lower_bounds.tolist()
        assert a.energies.tolist() == b.energies.tolist()
    h = rng.uniform(0, 1, 30)
    cost = GridCost(LabelGrid((10, 3), (0.3, 0.7), (True, False)), 1.3, 0.9)
    assert grid_message(h, cost).tolist() == grid_message(h, cost, backend="python").tolist()


def test_node_order_and_isolated_nodes() -> None:
    mrf = PairwiseMRF([[1.0, 0.0], [0.0, 2.0, 3.0], [0.5, 0.25]])
    mrf.add_dense_edge(2, 0, [[0.0, 1.0], [1.0, 0.0]])
    # node 1 has no edge: it takes its best unary label
    for order in ([0, 1, 2], [2, 1, 0], [1, 2, 0]):
        res = trws(mrf, order=order)
        assert res.labels.tolist() == [1, 0, 1]
        assert res.energy == pytest.approx(0.25)
        assert res.lower_bound == pytest.approx(0.25)
    no_edges = PairwiseMRF(np.array([[2.0, 1.0, 3.0]]))
    assert trws(no_edges).labels.tolist() == [1]


def test_stopping_rules() -> None:
    mrf = pose_like_mrf(1)
    res = trws(mrf, max_iter=3, tol=None)
    assert res.iterations == 3 and not res.converged and res.reason == "max_iter reached"
    res = trws(mrf, max_iter=500, tol=1e-6)
    assert res.converged and res.iterations < 500
    assert res.gap >= -1e-9


# ----------------------------------------------------------------------------- building, energy, graphs


def test_energy_and_edge_orientation() -> None:
    mrf = PairwiseMRF([[0.0, 1.0], [0.0, 0.0, 0.0]])
    mrf.add_dense_edge(1, 0, np.arange(6.0).reshape(3, 2))  # indexed [x_1, x_0]
    assert energy(mrf, [1, 2]) == 1.0 + 5.0
    assert energy(mrf, [0, 1]) == 2.0
    assert mrf.edge_cost(0).shape == (3, 2)
    res = trws(mrf)
    assert energy(mrf, res.labels) == res.energy == 0.0


def test_from_networkx() -> None:
    g = nx.Graph()
    g.add_node("a", unary=[0.0, 1.0])
    g.add_node("b", unary=[1.0, 0.0, 0.5])
    g.add_node("c", unary=[0.2, 0.0, 0.1])
    g.add_edge("b", "a", cost=np.ones((2, 3)), rows="a")
    g.add_edge("b", "c", cost=GridCost(LabelGrid((3,)), 1.0))
    mrf = PairwiseMRF.from_networkx(g)
    assert mrf.n_nodes == 3 and mrf.n_edges == 2
    assert mrf.edge_cost(0).shape == (2, 3)
    lab = np.array([0, 2, 2])
    assert energy(mrf, lab) == pytest.approx(0.0 + 0.5 + 0.1 + 1.0 + 0.0)
    g.add_edge("a", "c", cost=np.arange(6.0).reshape(2, 3))
    with pytest.raises(ValueError, match="needs the edge attribute 'rows'"):
        PairwiseMRF.from_networkx(g)


def test_knn_edges() -> None:
    rng = np.random.default_rng(0)
    pts = rng.uniform(0, 1, (50, 2))
    e = knn_edges(pts, 6)
    assert e.ndim == 2 and e.shape[1] == 2 and np.all(e[:, 0] < e[:, 1])
    assert len(np.unique(e, axis=0)) == len(e)
    deg = np.bincount(e.ravel(), minlength=50)
    assert deg.min() >= 6 and len(e) <= 50 * 6
    g = nx.Graph()
    g.add_edges_from(e.tolist())
    d = np.linalg.norm(pts[:, None] - pts[None], axis=2)
    np.fill_diagonal(d, np.inf)
    for i in range(50):
        for j in np.argsort(d[i])[:6]:
            assert g.has_edge(i, int(j))


# ----------------------------------------------------------------------------- bad inputs


def test_bad_inputs_raise_clear_errors() -> None:
    with pytest.raises(ValueError, match=r"expected an \(N, L\) array"):
        PairwiseMRF(np.zeros((2, 3, 4)))
    with pytest.raises(ValueError, match="at least one node"):
        PairwiseMRF([])
    with pytest.raises(ValueError, match=r"unaries\[1\]: expected a non-empty 1-D"):
        PairwiseMRF([[1.0, 2.0], [[1.0], [2.0]]])
    with pytest.raises(ValueError, match=r"unaries\[0\]: expected finite costs"):
        PairwiseMRF([[np.nan, 1.0]])
    mrf = PairwiseMRF(np.zeros((3, 2)))
    with pytest.raises(ValueError, match=r"expected shape \(L_i, L_j\) = \(2, 2\), got \(3, 2\)"):
        mrf.add_dense_edge(0, 1, np.zeros((3, 2)))
    with pytest.raises(ValueError, match="expected finite costs, got NaN"):
        mrf.add_dense_edge(0, 1, [[0.0, np.nan], [1.0, 0.0]])
    with pytest.raises(ValueError, match="edge to a missing node"):
        mrf.add_dense_edge(0, 3, np.zeros((2, 2)))
    with pytest.raises(ValueError, match="edge to a missing node"):
        mrf.add_dense_edge(-1, 0, np.zeros((2, 2)))
    with pytest.raises(ValueError, match="self-loop"):
        mrf.add_dense_edge(1, 1, np.zeros((2, 2)))
    mrf.add_dense_edge(0, 1, np.zeros((2, 2)))
    with pytest.raises(ValueError, match="at most one edge per node pair"):
        mrf.add_dense_edge(1, 0, np.zeros((2, 2)))
    with pytest.raises(ValueError, match=r"gamma >= 0"):
        GridCost(LabelGrid((2,)), 1.0, gamma=-0.1)
    with pytest.raises(ValueError, match=r"gamma >= 0"):
        GridCost(LabelGrid((2,)), 1.0, gamma=float("nan"))
    with pytest.raises(ValueError, match=r"weight >= 0"):
        GridCost(LabelGrid((2,)), -1.0)
    with pytest.raises(ValueError, match="expected a finite number"):
        GridCost(LabelGrid((2,)), float("nan"))
    with pytest.raises(ValueError, match="metric"):
        GridCost(LabelGrid((2,)), 1.0, metric="l2")  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="positive steps"):
        LabelGrid((2, 3), steps=(1.0, 0.0))
    with pytest.raises(ValueError, match="one step and one cyclic flag per axis"):
        LabelGrid((2, 3), steps=(1.0,))
    with pytest.raises(ValueError, match="grid.size = 3 labels, got 2 and 2"):
        mrf.add_grid_edge(1, 2, GridCost(LabelGrid((3,)), 1.0))
    with pytest.raises(ValueError, match=r"weights: expected finite weights >= 0"):
        mrf.add_grid_edges([[1, 2]], LabelGrid((2,)), [np.nan])
    with pytest.raises(ValueError, match=r"labels: expected shape \(N,\) = \(3,\)"):
        energy(mrf, [0, 1])
    with pytest.raises(ValueError, match=r"labels\[2\]: expected a label in \[0, 2\)"):
        energy(mrf, [0, 1, 2])
    with pytest.raises(ValueError, match="order: expected a permutation"):
        trws(mrf, order=[0, 0, 1])
    with pytest.raises(ValueError, match="max_iter"):
        trws(mrf, max_iter=0)
    with pytest.raises(ValueError, match="tol"):
        trws(mrf, tol=-1.0)
    with pytest.raises(ValueError, match="backend"):
        trws(mrf, backend="gpu")  # type: ignore[arg-type]
    with pytest.raises(ValueError, match=r"h: expected shape \(L,\) = \(4,\)"):
        grid_message(np.zeros(3), GridCost(LabelGrid((4,)), 1.0))
    with pytest.raises(ValueError, match="h: expected finite costs"):
        grid_message([0.0, np.inf], GridCost(LabelGrid((2,)), 1.0))
    with pytest.raises(ValueError, match="k: expected an integer in"):
        knn_edges(np.zeros((4, 2)), 4)
