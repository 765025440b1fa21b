"""Array kernels of the TRW-S solver (private; see :mod:`posecrf.trws`).

The functions here work on flat float64/int64 arrays only. They are compiled
with numba (``njit(cache=True)``) when numba can be imported; otherwise, or
when this file is loaded by :func:`posecrf.trws._kernels` with
``_PANO2CAD_FORCE_PYTHON`` set, they run as plain Python. Both executions run
the very same statements in the same order (fastmath limited to "no NaNs" and
"no signed zeros", no reassociation, no contraction), so the results are
identical whichever backend runs them.

Convention: a label grid of shape ``(n_0, ..., n_{D-1})`` numbers its labels in
C order (``numpy.ravel_multi_index``); the stride of axis ``a`` is the product
of the sizes of the axes after it. Edge kinds: 0 dense matrix, 1 grid with the
truncated L1 distance, 2 grid with the truncated squared-L2 distance.
"""

from __future__ import annotations

import numpy as np

KIND_DENSE = 0
KIND_L1 = 1
KIND_L2SQ = 2

STATUS_MAX_ITER = 0
STATUS_GAP_CLOSED = 1
STATUS_STALLED = 2

if globals().get("_PANO2CAD_FORCE_PYTHON", False):
    BACKEND = "python"
else:
    try:
        import numba as _numba
    except ImportError:
        BACKEND = "python"
    else:
        BACKEND = "numba"

# 'nnan' and 'nsz' only let LLVM vectorise min-selects; no reassociation and no
# contraction, so every value equals the one the plain Python run computes.
_FASTMATH = {"nnan", "nsz"}


def _jit(func):  # type: ignore[no-untyped-def]
    if BACKEND == "numba":
        return _numba.njit(cache=True, nogil=True, fastmath=_FASTMATH)(func)
    return func


@_jit
def l1_axis_pass(buf, n, stride, c, cyclic, k_wrap):  # type: ignore[no-untyped-def]
    """In place: buf[p] <- min_q buf[q] + c * |p - q| along one axis of a C-order grid.

    Felzenszwalb-Huttenlocher two-pass distance transform for the linear (L1)
    cost: linear in the number of labels. On a cyclic axis each pass goes on
    for ``k_wrap`` positions past the seam (a full lap when k_wrap == n), which
    covers every wrapped path of at most k_wrap steps.
    """
    block = n * stride
    nouter = buf.shape[0] // block
    kw = min(k_wrap, n) if cyclic else 0
    if stride == 1:
        # one line at a time, the running minimum kept in a register
        for o in range(nouter):
            line = buf[o * n: o * n + n]
            prev = line[0]
            for k in range(1, n):
                v = prev + c
                b = line[k]
                prev = v if v < b else b
                line[k] = prev
            for k in range(kw):
                v = prev + c
                b = line[k]
                prev = v if v < b else b
                line[k] = prev
            prev = line[n - 1]
            for k in range(n - 2, -1, -1):
                v = prev + c
                b = line[k]
                prev = v if v < b else b
                line[k] = prev
            for t in range(kw):
                k = n - 1 - t
                v = prev + c
                b = line[k]
                prev = v if v < b else b
                line[k] = prev
        return
    for o in range(nouter):
        blk = buf[o * block: o * block + block]
        for k in range(1, n):
            cur = k * stride
            for r in range(stride):
                v = blk[cur - stride + r] + c
                b = blk[cur + r]
                blk[cur + r] = v if v < b else b
        for k in range(kw):
            cur = k * stride
            prev = ((k + n - 1) % n) * stride
            for r in range(stride):
                v = blk[prev + r] + c
                b = blk[cur + r]
                blk[cur + r] = v if v < b else b
        for k in range(n - 2, -1, -1):
            cur = k * stride
            for r in range(stride):
                v = blk[cur + stride + r] + c
                b = blk[cur + r]
                blk[cur + r] = v if v < b else b
        for t in range(kw):
            cur = (n - 1 - t) * stride
            nxt = ((n - t) % n) * stride
            for r in range(stride):
                v = blk[nxt + r] + c
                b = blk[cur + r]
                blk[cur + r] = v if v < b else b


@_jit
def sq_line(f, m, a, d, v, z):  # type: ignore[no-untyped-def]
    """d[p] = min_q f[q] + a * (p - q)**2 for p, q in [0, m): lower envelope of parabolas."""
    if a <= 0.0:
        mn = f[0]
        for q in range(1, m):
            mn = f[q] if f[q] < mn else mn
        for p in range(m):
            d[p] = mn
        return
    k = 0
    v[0] = 0
    z[0] = -np.inf
    z[1] = np.inf
    for q in range(1, m):
        while True:
            vk = v[k]
            # intersection of the parabolas of q and vk; written so that it is never NaN
            s = ((f[q] - f[vk]) / a + (q * q - vk * vk)) / (2.0 * (q - vk))
            if k > 0 and s <= z[k]:
                k -= 1
            else:
                break
        if s <= z[k]:
            # only when k == 0 and s == -inf (tiny a): parabola q lies below all kept ones
            v[0] = q
            z[1] = np.inf
            continue
        k += 1
        v[k] = q
        z[k] = s
        z[k + 1] = np.inf
    k = 0
    for p in range(m):
        while z[k + 1] < p:
            k += 1
        dp = p - v[k]
        d[p] = a * dp * dp + f[v[k]]


@_jit
def sq_axis_pass(buf, n, stride, a, cyclic, f, d, v, z):  # type: ignore[no-untyped-def]
    """In place: buf[p] <- min_q buf[q] + a * dist(p, q)**2 along one axis (cyclic: images at +-n)."""
    block = n * stride
    nouter = buf.shape[0] // block
    reps = 3 if cyclic else 1
    shift = n if cyclic else 0
    m = reps * n
    for o in range(nouter):
        base = o * block
        for r in range(stride):
            for j in range(m):
                f[j] = buf[base + (j % n) * stride + r]
            sq_line(f, m, a, d, v, z)
            for k in range(n):
                buf[base + k * stride + r] = d[k + shift]


@_jit
def grid_dt(buf, ndim, shape, step, cyc, w, gamma, kind, f, d, v, z):  # type: ignore[no-untyped-def]
    """In place: buf[x] <- min(min_y buf[y] + w * dist(y, x), w * gamma) over a label grid.

    Separable distance transforms, one pass per axis (L1: two linear sweeps,
    squared L2: lower envelope of parabolas). The cap ``w * gamma`` is the
    truncation exactly when ``min(buf) == 0`` on entry, which the callers
    ensure. ``shape``, ``step``, ``cyc`` hold the grid's axes (first ``ndim``
    entries); ``f, d, v, z`` are work buffers of at least 3 * max(shape) + 3 entries.
    """
    size = buf.shape[0]
    stride = size
    for ax in range(ndim):
        n = shape[ax]
        stride = stride // n
        if n == 1:
            continue
        if kind == KIND_L1:
            c = w * step[ax]
            k_wrap = n
            if c > 0.0 and gamma < np.inf:
                reach = gamma / step[ax]
                if reach < n:
                    k_wrap = int(reach) + 1
            l1_axis_pass(buf, n, stride, c, cyc[ax] != 0, k_wrap)
        else:
            sq_axis_pass(buf, n, stride, w * step[ax] * step[ax], cyc[ax] != 0, f, d, v, z)
    if gamma < np.inf:
        cap = w * gamma
        for x in range(size):
            b = buf[x]
            buf[x] = cap if cap < b else b


@_jit
def dense_message(h, out, cost, la, lb, from_a):  # type: ignore[no-untyped-def]
    """Min-sum product with a dense (la, lb) cost given row-major as the (la*lb,) array ``cost``.

    from_a: out[xb] = min_xa h[xa] + C[xa, xb]; otherwise out[xa] = min_xb h[xb] + C[xa, xb].
    """
    if from_a:
        h0 = h[0]
        for xb in range(lb):
            out[xb] = h0 + cost[xb]
        for xa in range(1, la):
            hv = h[xa]
            row = cost[xa * lb: xa * lb + lb]
            for xb in range(lb):
                val = hv + row[xb]
                b = out[xb]
                out[xb] = val if val < b else b
    else:
        for xa in range(la):
            row = cost[xa * lb: xa * lb + lb]
            best = h[0] + row[0]
            for xb in range(1, lb):
                val = h[xb] + row[xb]
                best = val if val < best else best
            out[xa] = best


@_jit
def grid_cost_add(out, x0, ndim, shape, step, cyc, w, gamma, kind, tab):  # type: ignore[no-untyped-def]
    """out[x] += w * min(dist(x0, x), gamma) for every label x of the grid ((L,) array ``out``).

    ``tab`` is a work buffer of at least ndim * max(shape) + L floats. The
    distance is summed in axis order, as :meth:`posecrf.mrf.LabelGrid.distance` does.
    """
    size = out.shape[0]
    max_n = 0
    for ax in range(ndim):
        max_n = max(max_n, shape[ax])
    rem = x0
    for ax in range(ndim - 1, -1, -1):
        c0 = rem % shape[ax]
        rem = rem // shape[ax]
        for k in range(shape[ax]):
            delta = abs(k - c0)
            if cyc[ax] != 0 and shape[ax] - delta < delta:
                delta = shape[ax] - delta
            t = step[ax] * delta
            tab[ax * max_n + k] = t if kind == KIND_L1 else t * t
    # expand the per-axis terms into the (L,) distances, axis by axis, in place
    dist = tab[ndim * max_n: ndim * max_n + size]
    dist[0] = 0.0
    filled = 1
    for ax in range(ndim):
        n = shape[ax]
        t_ax = tab[ax * max_n: ax * max_n + n]
        for p in range(filled - 1, -1, -1):
            base = dist[p]
            for k in range(n - 1, -1, -1):
                dist[p * n + k] = base + t_ax[k]
        filled *= n
    for x in range(size):
        dx = dist[x]
        dx = gamma if gamma < dx else dx
        out[x] += w * dx


@_jit
def _belief(i, di, lab_off, unary, adj_ptr, adj_edge, ea, msg, moff_a, moff_b):  # type: ignore[no-untyped-def]
    """di[:L_i] <- unary_i + all messages into i; returns L_i."""
    lo = lab_off[i]
    li = lab_off[i + 1] - lo
    u = unary[lo: lo + li]
    for x in range(li):
        di[x] = u[x]
    for p in range(adj_ptr[i], adj_ptr[i + 1]):
        e = adj_edge[p]
        mo = moff_a[e] if ea[e] == i else moff_b[e]
        m = msg[mo: mo + li]
        for x in range(li):
            di[x] += m[x]
    return li


@_jit
def _send(  # type: ignore[no-untyped-def]
    i, rank, di, hb, lab_off, ea, eb, kind, cost_off, costs, gid, wts, gam,
    g_ndim, g_shape, g_step, g_cyc, adj_ptr, adj_edge, gnode, msg, moff_a, moff_b, f, d, v, z,
):
    """Update the messages from i to the neighbours j with rank[j] > rank[i].

    ``rank`` is the position in ``order`` for the forward pass and the
    position counted from the end for the backward pass.

    ``h = gnode[i] * di - (message into i)``; the new message into j is
    ``min_xi h[xi] + cost(xi, xj)`` minus its minimum. Returns the sum of the
    subtracted minima (the lower-bound contribution).
    """
    li = lab_off[i + 1] - lab_off[i]
    gi = gnode[i]
    total = 0.0
    for p in range(adj_ptr[i], adj_ptr[i + 1]):
        e = adj_edge[p]
        i_is_a = ea[e] == i
        j = eb[e] if i_is_a else ea[e]
        if rank[j] <= rank[i]:
            continue
        lj = lab_off[j + 1] - lab_off[j]
        mo_i = moff_a[e] if i_is_a else moff_b[e]
        mo_j = moff_b[e] if i_is_a else moff_a[e]
        mi = msg[mo_i: mo_i + li]
        mj = msg[mo_j: mo_j + lj]
        if kind[e] == KIND_DENSE:
            h = hb[:li]
            for x in range(li):
                h[x] = gi * di[x] - mi[x]
            la = li if i_is_a else lj
            lbn = lj if i_is_a else li
            dense_message(h, mj, costs[cost_off[e]: cost_off[e] + la * lbn], la, lbn, i_is_a)
            vmin = mj[0]
            for x in range(lj):
                t = mj[x]
                vmin = t if t < vmin else vmin
            for x in range(lj):
                mj[x] -= vmin
        else:
            # h = gi * di - mi goes straight into the outgoing slot, shifted to min 0
            vmin = gi * di[0] - mi[0]
            for x in range(li):
                t = gi * di[x] - mi[x]
                mj[x] = t
                vmin = t if t < vmin else vmin
            for x in range(li):
                mj[x] -= vmin
            g = gid[e]
            grid_dt(mj, g_ndim[g], g_shape[g], g_step[g], g_cyc[g], wts[e], gam[e], kind[e], f, d, v, z)
        total += vmin
    return total


@_jit
def grid_cost_one(x0, x1, ndim, shape, step, cyc, w, gamma, kind):  # type: ignore[no-untyped-def]
    """w * min(dist(x0, x1), gamma) for two labels of a grid (same arithmetic as :func:`grid_cost_add`)."""
    dist = 0.0
    stride = 1
    for ax in range(ndim):
        stride *= shape[ax]
    for ax in range(ndim):
        stride = stride // shape[ax]
        delta = abs((x0 // stride) % shape[ax] - (x1 // stride) % shape[ax])
        if cyc[ax] != 0 and shape[ax] - delta < delta:
            delta = shape[ax] - delta
        t = step[ax] * delta
        dist = dist + (t if kind == KIND_L1 else t * t)
    dist = gamma if gamma < dist else dist
    return w * dist


@_jit
def _belief_decode(i, di, dd, labels, lab_off, unary, pos, ea, eb, kind, cost_off, costs, gid, wts, gam,
                   g_ndim, g_shape, g_step, g_cyc, adj_ptr, adj_edge, msg, moff_a, moff_b,
                   tab):  # type: ignore[no-untyped-def]
    """Belief of i (unary + all messages into i) in ``di`` and the label of i in ``labels[i]``.

    The label minimises unary + costs to the labels of the earlier neighbours
    + messages from the later neighbours (Kolmogorov's decoding); in a
    forward pass the later neighbours' messages are still those of the last
    backward pass. Returns (L_i, cost of the label: unary + edges to earlier nodes).
    """
    lo = lab_off[i]
    li = lab_off[i + 1] - lo
    u = unary[lo: lo + li]
    for x in range(li):
        di[x] = u[x]
        dd[x] = u[x]
    for p in range(adj_ptr[i], adj_ptr[i + 1]):
        e = adj_edge[p]
        i_is_a = ea[e] == i
        j = eb[e] if i_is_a else ea[e]
        mo = moff_a[e] if i_is_a else moff_b[e]
        m = msg[mo: mo + li]
        for x in range(li):
            di[x] += m[x]
        if pos[j] > pos[i]:
            for x in range(li):
                dd[x] += m[x]
        elif kind[e] == KIND_DENSE:
            xj = labels[j]
            if i_is_a:
                lbn = lab_off[j + 1] - lab_off[j]
                for x in range(li):
                    dd[x] += costs[cost_off[e] + x * lbn + xj]
            else:
                row = costs[cost_off[e] + xj * li: cost_off[e] + xj * li + li]
                for x in range(li):
                    dd[x] += row[x]
        else:
            g = gid[e]
            grid_cost_add(dd[:li], labels[j], g_ndim[g], g_shape[g], g_step[g], g_cyc[g], wts[e], gam[e],
                          kind[e], tab)
    xb = 0
    for x in range(1, li):
        if dd[x] < dd[xb]:
            xb = x
    labels[i] = xb
    cost = u[xb]
    for p in range(adj_ptr[i], adj_ptr[i + 1]):
        e = adj_edge[p]
        i_is_a = ea[e] == i
        j = eb[e] if i_is_a else ea[e]
        if pos[j] < pos[i]:
            if kind[e] == KIND_DENSE:
                lbn = lab_off[eb[e] + 1] - lab_off[eb[e]]
                cost += costs[cost_off[e] + xb * lbn + labels[j]] if i_is_a else costs[
                    cost_off[e] + labels[j] * lbn + xb]
            else:
                g = gid[e]
                cost += grid_cost_one(labels[j], xb, g_ndim[g], g_shape[g], g_step[g], g_cyc[g], wts[e], gam[e],
                                      kind[e])
    return li, cost


@_jit
def fw_chunk(nodes, a, b, send, node_e, labels, di, dd, hb, tab, fb, dbuf, vb, zb, lab_off, unary, pos, ea, eb,
             kind, cost_off, costs, gid, wts, gam, g_ndim, g_shape, g_step, g_cyc, adj_ptr, adj_edge, gnode, msg,
             moff_a, moff_b):  # type: ignore[no-untyped-def]
    """Forward pass over nodes[a:b] in that order: decode each node, then (if ``send``) update its messages.

    The labels decoded are those of the messages left by the last backward pass.
    """
    for q in range(a, b):
        i = nodes[q]
        li, cost = _belief_decode(i, di, dd, labels, lab_off, unary, pos, ea, eb, kind, cost_off, costs, gid,
                                  wts, gam, g_ndim, g_shape, g_step, g_cyc, adj_ptr, adj_edge, msg, moff_a,
                                  moff_b, tab)
        node_e[i] = cost
        if send:
            _send(i, pos, di, hb, lab_off, ea, eb, kind, cost_off, costs, gid, wts, gam,
                  g_ndim, g_shape, g_step, g_cyc, adj_ptr, adj_edge, gnode, msg, moff_a, moff_b, fb, dbuf, vb, zb)


@_jit
def bw_chunk(nodes, a, b, node_min, node_send, di, hb, fb, dbuf, vb, zb, lab_off, unary, rpos, ea, eb, kind,
             cost_off, costs, gid, wts, gam, g_ndim, g_shape, g_step, g_cyc, adj_ptr, adj_edge, gnode, msg,
             moff_a, moff_b):  # type: ignore[no-untyped-def]
    """Backward-pass updates of nodes[a:b]; stores each node's bound terms in node_min / node_send."""
    for q in range(a, b):
        i = nodes[q]
        li = _belief(i, di, lab_off, unary, adj_ptr, adj_edge, ea, msg, moff_a, moff_b)
        vmin = di[0]
        for x in range(li):
            tv = di[x]
            vmin = tv if tv < vmin else vmin
        for x in range(li):
            di[x] -= vmin
        node_min[i] = vmin
        node_send[i] = _send(i, rpos, di, hb, lab_off, ea, eb, kind, cost_off, costs, gid, wts, gam,
                             g_ndim, g_shape, g_step, g_cyc, adj_ptr, adj_edge, gnode, msg, moff_a, moff_b,
                             fb, dbuf, vb, zb)


@_jit
def end_iteration(  # type: ignore[no-untyped-def]
    it, tol, order, node_min, node_send, node_e, labels, best_labels, lb_hist, e_hist, state
):
    """Sum the bound and energy in ``order``, keep the best labelling, test the stopping rules.

    ``state`` = [best energy, previous bound]. Returns the status (-1: go on).
    """
    n_nodes = order.shape[0]
    lb = 0.0
    for r in range(n_nodes - 1, -1, -1):
        i = order[r]
        lb += node_min[i]
        lb += node_send[i]
    e_val = 0.0
    for r in range(n_nodes):
        e_val += node_e[order[r]]
    lb_hist[it] = lb
    e_hist[it] = e_val
    if e_val < state[0]:
        state[0] = e_val
        for k in range(n_nodes):
            best_labels[k] = labels[k]
    best_e = state[0]
    if best_e - lb <= 1e-9 * max(1.0, abs(best_e)):
        return STATUS_GAP_CLOSED
    if tol >= 0.0 and it > 0 and lb - state[1] <= tol * max(1.0, abs(lb)):
        return STATUS_STALLED
    state[1] = lb
    return -1


@_jit
def run(  # type: ignore[no-untyped-def]
    max_iter, tol, lab_off, unary, order, pos, ea, eb, kind, cost_off, costs, gid, wts, gam,
    g_ndim, g_shape, g_step, g_cyc, adj_ptr, adj_edge, gnode, msg, moff_a, moff_b,
    lb_hist, e_hist, labels, best_labels, max_l, max_n,
):
    """TRW-S main loop (Kolmogorov 2006, sequential schedule). Returns (iterations, status)."""
    n_nodes = order.shape[0]
    nd = g_shape.shape[1]
    di = np.empty(max_l)
    dd = np.empty(max_l)
    hb = np.empty(max_l)
    fb = np.empty(3 * max_n + 3)
    dbuf = np.empty(3 * max_n + 3)
    vb = np.empty(3 * max_n + 3, dtype=np.int64)
    zb = np.empty(3 * max_n + 4)
    tab = np.empty(nd * max_n + max_l)
    node_min = np.zeros(n_nodes)
    node_send = np.zeros(n_nodes)
    node_e = np.zeros(n_nodes)
    state = np.array([np.inf, -np.inf])
    reverse = order[::-1].copy()
    rpos = (n_nodes - 1) - pos
    for it in range(max_iter + 1):
        # forward pass; it also decodes the labelling of the previous iteration
        fw_chunk(order, 0, n_nodes, it < max_iter, node_e, labels, di, dd, hb, tab, fb, dbuf, vb, zb, lab_off,
                 unary, pos, ea, eb, kind, cost_off, costs, gid, wts, gam, g_ndim, g_shape, g_step, g_cyc, adj_ptr,
                 adj_edge, gnode, msg, moff_a, moff_b)
        if it > 0:
            status = end_iteration(it - 1, tol, order, node_min, node_send, node_e, labels, best_labels, lb_hist,
                                   e_hist, state)
            if status >= 0:
                return it, status
        if it == max_iter:
            break
        # backward pass: messages to earlier nodes and the lower bound
        bw_chunk(reverse, 0, n_nodes, node_min, node_send, di, hb, fb, dbuf, vb, zb, lab_off, unary, rpos, ea,
                 eb, kind, cost_off, costs, gid, wts, gam, g_ndim, g_shape, g_step, g_cyc, adj_ptr, adj_edge,
                 gnode, msg, moff_a, moff_b)
    return max_iter, STATUS_MAX_ITER


def order_weights(order: np.ndarray, ea: np.ndarray, eb: np.ndarray, n_nodes: int) -> tuple[np.ndarray, np.ndarray]:
    """Position of each node in ``order`` and the TRW-S node weights 1 / max(#earlier, #later neighbours)."""
    pos = np.empty(n_nodes, dtype=np.int64)
    pos[order] = np.arange(n_nodes, dtype=np.int64)
    later_b = pos[eb] > pos[ea]
    n_fwd = np.bincount(np.where(later_b, ea, eb), minlength=n_nodes)
    n_bwd = np.bincount(np.where(later_b, eb, ea), minlength=n_nodes)
    n_max = np.maximum(n_fwd, n_bwd)
    gnode = np.zeros(n_nodes, dtype=np.float64)
    np.divide(1.0, n_max, out=gnode, where=n_max > 0)
    return pos, gnode
