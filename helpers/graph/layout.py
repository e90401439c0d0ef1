"""What ``initialize_optimization`` builds once per change of the graph's elements: the free state vector X, where
every edge reads its vertices and writes its blocks of H and b, and the gauge check.

Free state: the free (alive, not fixed) vertices stacked in the order they were added; vertex handle h gets the
rows ``hessian_index[h]`` … ``+ dimension`` of X (−1 when fixed or removed).

H's pattern: an edge with the whitened Jacobians A = W [J_0 J_1 …] adds AᵀA to H at the rows and columns of its
free vertices and Aᵀr to b at their rows (r = W e). Only H's upper triangle is stored, in compressed-column (CSC)
form; every stored entry of every edge gets its position in H's data array once, here, and each linearisation
adds the values in place (``add_normal_equations``, compiled: the optimiser runs thousands of times in DriveBot).

Gauge check: free vertices joined by an edge are connected; a component is anchored if one of its vertices is in
an edge with a fixed vertex or in a unary (prior) edge. An unanchored component can move as a whole without
changing χ², so H is singular: ``GaugeFreedomError`` names its vertices.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
from numba import njit
from scipy.sparse.csgraph import connected_components

from .errors import GaugeFreedomError
from .storage import VertexStore

__all__ = ["VertexGroup", "EdgeClassLayout", "Layout", "free_state_layout", "build_layout", "check_gauge",
           "add_normal_equations"]


@dataclass
class VertexGroup:
    """The free vertices of one vertex class (⊞ is applied per class)."""

    cls: type
    state_index: np.ndarray    # (V, d) positions of their coordinates in the flat estimate array
    hessian_rows: np.ndarray   # (V, d) their rows in X
    handles: np.ndarray        # (V,) vertex handles


@dataclass
class EdgeClassLayout:
    """The live edges of one class: where they read their vertices and where their H and b entries go."""

    store: object              # the EdgeStore (its measurements, whitening and parameters are read at each use)
    rows: np.ndarray           # (E,) the store rows of the live edges
    state_index: list          # per slot k: (E, d_k) positions of the slot vertex's coordinates in the estimates
    x_rows: np.ndarray         # (E, D) rows in X of the columns of J = [J_0 J_1 …], −1 where the vertex is fixed
    h_index: np.ndarray        # (E, D, D) position of (AᵀA)_ij in H's CSC data, −1 where it is not stored


@dataclass
class Layout:
    """Everything ``initialize_optimization`` computes; valid until the elements change."""

    dimension: int             # n, the size of X
    hessian_index: np.ndarray  # per vertex handle: first row in X, −1 when fixed or removed
    groups: list               # [VertexGroup]
    edges: list                # [EdgeClassLayout]
    indptr: np.ndarray         # H's upper triangle, CSC
    indices: np.ndarray
    diagonal: np.ndarray       # (n,) positions of H's diagonal in the CSC data

    @property
    def nnz(self) -> int:
        return len(self.indices)


def free_state_layout(vertex_store: VertexStore) -> tuple:
    """(hessian_index per handle, n, free handles, [VertexGroup]) of the vertices stored now."""
    free = vertex_store.alive.values & ~vertex_store.fixed.values
    dims = vertex_store.dimension.values
    hessian_index = np.full(vertex_store.count, -1, dtype=np.int64)
    hessian_index[free] = np.cumsum(dims[free]) - dims[free]
    free_handles = np.nonzero(free)[0]
    groups = []
    codes = vertex_store.class_code.values[free_handles]
    for code in np.unique(codes):
        handles = free_handles[codes == code]
        cls = vertex_store.classes[code]
        ar = np.arange(int(cls.dimension))
        groups.append(VertexGroup(cls, vertex_store.offset.values[handles][:, None] + ar,
                                  hessian_index[handles][:, None] + ar, handles))
    return hessian_index, int(dims[free].sum()), free_handles, groups


def build_layout(vertex_store: VertexStore, edge_stores: dict) -> Layout:
    """The ``Layout`` of the graph's elements; raises GaugeFreedomError when a free component floats."""
    hessian_index, n, free_handles, groups = free_state_layout(vertex_store)
    offset = vertex_store.offset.values
    edges, keys, links = [], [], []
    for store in edge_stores.values():
        rows = store.alive_rows()
        if len(rows) == 0:
            continue
        handles = store.handles.values[rows]
        starts = [hessian_index[handles[:, k]] for k in range(store.slots)]
        # the rows in X of the D columns of A = [A_0 A_1 …], −1 where the slot's vertex is fixed
        x_rows = np.concatenate([np.where(s[:, None] >= 0, s[:, None] + np.arange(d), -1)
                                 for s, d in zip(starts, store.slot_dimensions)], axis=1)
        r, c = x_rows[:, :, None], x_rows[:, None, :]
        h_kept = np.flatnonzero((r >= 0) & (c >= 0) & (r <= c))         # AᵀA's entries in H's upper triangle
        edges.append(EdgeClassLayout(store, rows, [offset[handles[:, k]][:, None] + np.arange(d)
                                                   for k, d in enumerate(store.slot_dimensions)],
                                     x_rows, h_kept))                     # h_index is filled in below
        keys.append((c + 0 * r).ravel()[h_kept] * max(n, 1) + (r + 0 * c).ravel()[h_kept])
        links.append(_gauge_links(starts, handles))
    check_gauge(free_handles, vertex_store.count, [a for link in links for a in link[0]],
                [b for link in links for b in link[1]], [h for link in links for h in link[2]], vertex_store.objects)
    # the diagonal is always in the pattern (LM adds μ there), even where no edge reaches it
    keys.append(np.arange(n, dtype=np.int64) * max(n, 1) + np.arange(n, dtype=np.int64))
    unique, position = np.unique(np.concatenate(keys), return_inverse=True)
    col, row = np.divmod(unique, max(n, 1))
    at = 0
    for layout in edges:
        kept, layout.h_index = layout.h_index, np.full(layout.x_rows.shape + layout.x_rows.shape[1:], -1, np.int64)
        layout.h_index.ravel()[kept] = position[at:at + len(kept)]
        at += len(kept)
    indptr = np.searchsorted(col, np.arange(n + 1)).astype(np.int64)
    return Layout(n, hessian_index, groups, edges, indptr, row.astype(np.int64), position[at:at + n])


def _gauge_links(starts: list, handles: np.ndarray) -> tuple:
    """(pairs of free handles joined by an edge, as two lists of arrays; handles of anchored free vertices)."""
    free = [s >= 0 for s in starts]
    any_fixed = ~np.logical_and.reduce(free)
    link_a, link_b, anchored = [], [], []
    for k in range(len(starts)):
        for l in range(k + 1, len(starts)):
            both = free[k] & free[l]
            link_a.append(handles[both, k])
            link_b.append(handles[both, l])
        anchored.append(handles[free[k] if len(starts) == 1 else free[k] & any_fixed, k])
    return link_a, link_b, anchored


def check_gauge(free_handles: np.ndarray, handle_count: int, link_a: list, link_b: list, anchored_handles: list,
                vertex_objects: list) -> None:
    """Raise GaugeFreedomError unless every connected component of free vertices has an anchored vertex.

    ``link_a``/``link_b``: lists of arrays of free handles joined by an edge; ``anchored_handles``: list of arrays
    of free handles in an edge with a fixed vertex or in a unary edge; ``vertex_objects[h]`` names the vertices.
    """
    nf = len(free_handles)
    if nf == 0:
        return
    rank = np.full(handle_count, -1, dtype=np.int64)
    rank[free_handles] = np.arange(nf)
    a = rank[np.concatenate(link_a)] if link_a else np.zeros(0, dtype=np.int64)
    b = rank[np.concatenate(link_b)] if link_b else np.zeros(0, dtype=np.int64)
    ncomp, labels = connected_components(sp.coo_matrix((np.ones(len(a)), (a, b)), shape=(nf, nf)), directed=False)
    anchored = np.zeros(ncomp, dtype=bool)
    if anchored_handles:
        anchored[labels[rank[np.concatenate(anchored_handles)]]] = True
    if anchored.all():
        return
    bad = np.nonzero(~anchored)[0]
    comps = [[vertex_objects[h] for h in free_handles[labels == c]] for c in bad[:5]]
    first = comps[0]
    names = ", ".join(f"{type(v).__name__} {v.id}" for v in first[:8])
    more = "" if len(first) <= 8 else f", … ({len(first)} vertices)"
    raise GaugeFreedomError(
        f"{len(bad)} connected component(s) of free vertices have no fixed vertex and no unary (prior) edge, "
        f"so their position is undetermined (gauge freedom); first component: {len(first)} vertices "
        f"[{names}{more}]. Fix a vertex (set_fixed(True)) or add a prior edge.", comps)


@njit(cache=True)
def add_normal_equations(w: np.ndarray, e: np.ndarray, jac: np.ndarray, x_rows: np.ndarray, h_index: np.ndarray,
                         hessian: np.ndarray, gradient: np.ndarray) -> float:
    """Add the edges of one class to H's CSC data ``hessian`` and to ``gradient`` (b); returns their χ².

    w (E, m, m) whitening (Ω = WᵀW), e (E, m) errors, jac (E, m, D) the Jacobians J = [J_0 J_1 …] side by side,
    x_rows (E, D) and h_index (E, D, D) from the layout (−1: not stored)."""
    n_edges, m, n_cols = jac.shape
    chi2 = 0.0
    r = np.empty(m)
    a = np.empty((m, n_cols))
    for k in range(n_edges):
        # r = W e, the whitened error; χ² += rᵀr
        for i in range(m):
            r[i] = 0.0
            for j in range(m):
                r[i] += w[k, i, j] * e[k, j]
            chi2 += r[i] * r[i]
        # A = W J, the whitened Jacobian
        for i in range(m):
            for c in range(n_cols):
                a[i, c] = 0.0
                for j in range(m):
                    a[i, c] += w[k, i, j] * jac[k, j, c]
        for c in range(n_cols):
            row = x_rows[k, c]
            if row < 0:
                continue
            # b[row] += (Aᵀ r)_c
            for i in range(m):
                gradient[row] += a[i, c] * r[i]
            # H += AᵀA, upper triangle: (AᵀA)_cd = Σ_i A_ic A_id
            for d in range(n_cols):
                at = h_index[k, c, d]
                if at >= 0:
                    for i in range(m):
                        hessian[at] += a[i, c] * a[i, d]
    return chi2
