"""The structure of a graph, built by ``initialize_optimization`` once per change of its elements.

Free state. The free (alive, not fixed) vertices are stacked in creation order into the state vector X: vertex
handle h gets the Hessian rows ``hessian_index[h]`` … ``+ dimension`` (−1 for fixed or removed vertices).

Edges. For every edge class with live edges an ``EdgeClassBlock`` copies what an iteration needs: per slot the
positions of the slot vertices' coordinates in the flat estimate array and their first Hessian row, the
measurements, the whitening matrices (just their diagonals when all are diagonal) and the parameters.

Hessian pattern. Every edge contributes the blocks H_kl = J_kᵀ Ω J_l (k ≤ l) between its slots and b_k = J_kᵀ Ω e
to its slots; the contributions are listed in the order ``linearise.linearise`` produces their values (per class,
per slot k: H_kk, H_k(k+1), …, then b_k), and the ``HessianPattern`` maps them to CSC positions once (built from
the vertex blocks by ``block_pattern.pattern_from_blocks``; the same arrays as the reference constructor from one
(row, col) per scalar contribution).

Extension. When vertices and edges were only added since the last build (nothing removed, fixed, freed or
reconnected), ``extend_structure`` builds the same structure from the old one: the new free vertices take the rows
after the old ones, every edge class's old rows keep their gather arrays and Hessian positions, and only the new
edges' contributions are placed (``HessianPattern.extended``: they lie in the new columns, so the old CSC positions
do not move) and gauge-checked (the old components were anchored; a new vertex must reach one of them, a fixed
vertex or a prior through the new edges). An edge joining two old vertices cannot be placed that way: the build
then starts afresh. Either way the result equals ``build_structure``'s array for array.

Gauge check. Free vertices joined by an edge are connected; a component is anchored if one of its vertices is in
an edge with a fixed vertex or in a unary (prior) edge. An unanchored component can move as a whole without
changing χ², so H is singular: ``GaugeFreedomError`` names its vertices.
"""

import functools
from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import connected_components

from ...graph.layout import VertexGroup, check_gauge
from ...graph.layout import free_state_layout as course_free_state_layout
from .block_pattern import pattern_from_blocks
from .linear import HessianPattern

__all__ = ["GraphStructure", "EdgeClassBlock", "VertexGroup", "build_structure", "extend_structure", "check_gauge",
           "refresh_edge_values"]


@dataclass
class EdgeClassBlock:
    """The live edges of one class, as arrays (one build)."""

    store: object              # the EdgeStore (class, slot count, dimensions)
    rows: np.ndarray           # (E,) its alive rows
    handles: np.ndarray        # (E, slots) vertex handles
    state_index: list          # per slot k: (E, d_k) positions of the slot vertex's coordinates in the estimates
    hessian_start: list        # per slot k: (E,) first row of the slot vertex in X, −1 when fixed
    measurements: np.ndarray   # (E, m)
    whitening: np.ndarray      # W (E, m, m), or its diagonal (E, m) when ``diagonal_whitening``
    whitening_t: np.ndarray    # Wᵀ (E, m, m), contiguous (None when ``diagonal_whitening``)
    diagonal_whitening: bool
    params: dict               # name -> (E, *shape)

    @property
    def count(self):
        return len(self.rows)


@dataclass
class GraphStructure:
    """Everything ``initialize_optimization`` computes; valid until the elements change."""

    dimension: int             # n, size of X
    handle_count: int          # number of vertex handles at build time
    hessian_index: np.ndarray  # per handle: first row in X, −1 when fixed/removed
    vertex_groups: list        # [VertexGroup], one per vertex class with free vertices
    manifold: bool             # some free vertex class has a non-additive ⊞ (oplus_jacobian_batch)
    free_state_index: np.ndarray  # (n,) position in the flat estimate array of every entry of X
    blocks: list               # [EdgeClassBlock]
    pattern: HessianPattern
    gradient_rows: np.ndarray  # row in X of every b contribution (n for a fixed vertex: dropped)


def free_state_layout(vertex_store):
    """Hessian indices of the free vertices: (hessian_index, n, free handles, vertex groups, free_state_index)."""
    hessian_index, n, free_handles, groups = course_free_state_layout(vertex_store)
    free_state_index = np.zeros(n, dtype=np.int64)
    for g in groups:
        free_state_index[g.hessian_rows.ravel()] = g.state_index.ravel()
    return hessian_index, n, free_handles, groups, free_state_index


def edge_class_block(store, rows, offset, hessian_index):
    """The ``EdgeClassBlock`` of the given alive rows of one edge store."""
    handles = store.handles.values[rows]
    w = store.whitening.values[rows]                     # a copy (fancy indexing)
    ar = np.arange(store.measurement_dimension)
    diagonal = np.count_nonzero(w) == np.count_nonzero(w[:, ar, ar])   # every off-diagonal entry is 0
    return EdgeClassBlock(
        store=store, rows=rows, handles=handles,
        state_index=[offset[handles[:, k]][:, None] + np.arange(d) for k, d in enumerate(store.slot_dimensions)],
        hessian_start=[hessian_index[handles[:, k]] for k in range(store.slots)],
        measurements=store.measurements.values[rows],
        whitening=w[:, ar, ar] if diagonal else w,
        whitening_t=None if diagonal else np.ascontiguousarray(w.transpose(0, 2, 1)),
        diagonal_whitening=diagonal,
        params={k: g.values[rows] for k, g in store.params.items()})


def refresh_edge_values(structure, vertex_store, edge_classes):
    """Re-gather the measurements, whitening and parameters of the blocks of ``edge_classes`` (edited after the
    build): each such block is rebuilt over the same rows, exactly as ``build_structure`` would build it now. The
    rows, vertices and Hessian pattern do not change when only values do, so nothing else is recomputed."""
    offset = vertex_store.offset.values
    for i, block in enumerate(structure.blocks):
        if block.store.cls in edge_classes:
            structure.blocks[i] = edge_class_block(block.store, block.rows, offset, structure.hessian_index)


def hessian_blocks(block):
    """The block's H contributions per slot pair k ≤ l, in ``linearise``'s value order: a list of
    (hk, hl, d_k, d_l, k == l) — the slot vertices' first rows (−1 when fixed) and dimensions."""
    store, starts = block.store, block.hessian_start
    dims = store.slot_dimensions
    return [(starts[k], starts[l], dims[k], dims[l], k == l)
            for k in range(store.slots) for l in range(k, store.slots)]


def gradient_rows_of(block, n):
    """Per slot k: the rows in X of the block's b contributions (n where the slot vertex is fixed)."""
    out = []
    for hk, dk in zip(block.hessian_start, block.store.slot_dimensions):
        out.append(np.where(hk[:, None] >= 0, hk[:, None] + np.arange(dk), n).ravel())
    return out


@functools.cache
def _block_entries(dk, dl, same):
    """(i, j) of a slot pair's contributions within its block, in ``linearise``'s order: the upper triangle row by
    row when ``same`` (numpy.triu_indices), else the d_k × d_l block row by row (read-only arrays, cached)."""
    a, b = np.triu_indices(dk) if same else np.divmod(np.arange(dk * dl), dl)
    a.flags.writeable = b.flags.writeable = False
    return a, b


def hessian_contributions(block, n):
    """Positions of the block's H and b contributions: lists of (rows, cols, valid) arrays of the upper-triangle
    H entries, one entry per scalar contribution, and of the b rows (n where the slot vertex is fixed), in
    ``linearise``'s value order (the input of ``HessianPattern`` and ``HessianPattern.extended``)."""
    rows, cols, valid = [], [], []
    for hk, hl, dk, dl, same in hessian_blocks(block):
        a, b = _block_entries(dk, dl, same)
        r = hk[:, None] + a
        c = hl[:, None] + b
        rows.append(np.minimum(r, c).ravel())
        cols.append(np.maximum(r, c).ravel())
        valid.append(np.repeat((hk >= 0) & (hl >= 0), len(a)))
    return rows, cols, valid, gradient_rows_of(block, n)


def gauge_links(block):
    """Gauge bookkeeping of one block: (pairs of free handles joined by an edge as two lists, anchored handles)."""
    slots = block.store.slots
    fh = [block.handles[:, k] for k in range(slots)]
    isfree = [block.hessian_start[k] >= 0 for k in range(slots)]
    anyfixed = np.zeros(block.count, dtype=bool)
    for k in range(slots):
        anyfixed |= ~isfree[k]
    link_a, link_b, anchored = [], [], []
    for k in range(slots):
        for l in range(k + 1, slots):
            both = isfree[k] & isfree[l]
            link_a.append(fh[k][both])
            link_b.append(fh[l][both])
        if slots == 1:
            anchored.append(fh[k][isfree[k]])
        else:
            anchored.append(fh[k][isfree[k] & anyfixed])
    return link_a, link_b, anchored


def build_structure(vertex_store, edge_stores):
    """The ``GraphStructure`` of the current elements; raises GaugeFreedomError if a free component floats.
    The Hessian pattern comes from the vertex blocks (``block_pattern``; the same arrays as ``HessianPattern``
    from the scalar contributions)."""
    hessian_index, n, free_handles, groups, free_state_index = free_state_layout(vertex_store)
    offset = vertex_store.offset.values
    blocks, pairs, brow_all = [], [], []
    link_a, link_b, anchored = [], [], []
    for store in edge_stores.values():
        rows = store.alive_rows()
        if len(rows) == 0:
            continue
        block = edge_class_block(store, rows, offset, hessian_index)
        blocks.append(block)
        pairs += hessian_blocks(block)
        brow_all += gradient_rows_of(block, n)
        a, b, anc = gauge_links(block)
        link_a += a
        link_b += b
        anchored += anc

    check_gauge(free_handles, len(hessian_index), link_a, link_b, anchored, vertex_store.objects)

    brow_c = np.concatenate(brow_all) if brow_all else np.zeros(0, dtype=np.int64)
    pattern = pattern_from_blocks(n, hessian_index[free_handles], vertex_store.dimension.values[free_handles], pairs)
    return GraphStructure(
        dimension=n, handle_count=vertex_store.count, hessian_index=hessian_index, vertex_groups=groups,
        manifold=any(getattr(g.cls, 'oplus_jacobian_batch', None) is not None for g in groups),
        free_state_index=free_state_index,
        blocks=blocks, pattern=pattern, gradient_rows=brow_c)


def _contribution_widths(store):
    """Entries per edge of each H contribution group (slot pairs k ≤ l, ``hessian_contributions``' order) and of
    each b group (slot k)."""
    dims = store.slot_dimensions
    h = [dims[k] * (dims[k] + 1) // 2 if k == l else dims[k] * dims[l]
         for k in range(store.slots) for l in range(k, store.slots)]
    return h, list(dims)


def _interleave(old_blocks, plan, old_values, new_values, pick):
    """Per block of ``plan`` ((store, old row count, new row count)) and per contribution group (``pick`` of
    ``_contribution_widths``): the old block's segment of ``old_values`` followed by the new edges' segment of
    ``new_values`` — the order ``build_structure`` lists the contributions of all rows in."""
    old_at, pos = {}, 0
    for blk in old_blocks:
        old_at[id(blk.store)] = pos
        pos += blk.count * sum(pick(_contribution_widths(blk.store)))
    parts, new_pos = [], 0
    for store, e_old, e_new in plan:
        o = old_at.get(id(store), 0)
        for w in pick(_contribution_widths(store)):
            parts += [old_values[o:o + e_old * w], new_values[new_pos:new_pos + e_new * w]]
            o += e_old * w
            new_pos += e_new * w
    return np.concatenate(parts) if parts else np.zeros(0, dtype=np.int64)


def _gauge_extension_ok(old, free_handles, link_a, link_b, anchored_handles):
    """Whether every new free vertex reaches an anchored component through the new edges (``old`` passed its
    gauge check, so each old free vertex stands for an anchored component: node 0 below). Reachability spreads
    along the links a few rounds at a time (a new pose is one link from the graph); a long chain of new vertices
    falls back to connected components."""
    new_free = free_handles[free_handles >= old.handle_count]
    if new_free.size == 0:
        return True
    node = np.zeros(int(free_handles.max()) + 1, dtype=np.int64)
    node[new_free] = np.arange(1, new_free.size + 1)
    a = node[np.concatenate(link_a)] if link_a else np.zeros(0, dtype=np.int64)
    b = node[np.concatenate(link_b)] if link_b else np.zeros(0, dtype=np.int64)
    nodes = new_free.size + 1
    reached = np.zeros(nodes, dtype=bool)
    reached[0] = True
    if anchored_handles:
        reached[node[np.concatenate(anchored_handles)]] = True
    for _ in range(8):
        if reached.all():
            return True
        forward, backward = reached[a] & ~reached[b], reached[b] & ~reached[a]
        if not (forward.any() or backward.any()):
            return False
        reached[b[forward]] = True
        reached[a[backward]] = True
    ncomp, labels = connected_components(sp.coo_matrix((np.ones(len(a)), (a, b)), shape=(nodes, nodes)),
                                         directed=False)
    return bool(np.isin(labels, labels[reached]).all())


def _joined_block(old, fresh):
    """The block of ``old``'s rows followed by ``fresh``'s (one edge class), as ``edge_class_block`` would build it
    over all of them; None when one part has diagonal whitening and the other not."""
    if old.diagonal_whitening != fresh.diagonal_whitening:
        return None
    cat = np.concatenate
    return EdgeClassBlock(
        store=old.store, rows=cat([old.rows, fresh.rows]), handles=cat([old.handles, fresh.handles]),
        state_index=[cat(pair) for pair in zip(old.state_index, fresh.state_index)],
        hessian_start=[cat(pair) for pair in zip(old.hessian_start, fresh.hessian_start)],
        measurements=cat([old.measurements, fresh.measurements]), whitening=cat([old.whitening, fresh.whitening]),
        whitening_t=None if old.diagonal_whitening else cat([old.whitening_t, fresh.whitening_t]),
        diagonal_whitening=old.diagonal_whitening,
        params={k: cat([v, fresh.params[k]]) for k, v in old.params.items()})


def extend_structure(old, vertex_store, edge_stores, edited=()):
    """The structure of the current elements built from ``old`` (module docstring, Extension) when only vertices
    and edges were added since; None when it cannot be (an edge between two old vertices, or rows that are not
    an extension of the old ones), and the caller builds afresh. ``edited``: edge classes whose values changed
    since ``old`` was built (their blocks are gathered afresh). Raises GaugeFreedomError as ``build_structure``."""
    hessian_index, n, free_handles, groups, free_state_index = free_state_layout(vertex_store)
    if not np.array_equal(hessian_index[:old.handle_count], old.hessian_index):
        return None
    old_by_store = {id(blk.store): blk for blk in old.blocks}
    offset = vertex_store.offset.values
    blocks, plan, contributions, links = [], [], ([], [], [], []), ([], [], [])
    for store in edge_stores.values():
        rows = store.alive_rows()
        ob = old_by_store.pop(id(store), None)
        e_old = 0 if ob is None else ob.count
        if len(rows) < e_old or (e_old and not np.array_equal(rows[:e_old], ob.rows)):
            return None
        if len(rows) == 0:
            continue
        fresh = edge_class_block(store, rows[e_old:], offset, hessian_index) if len(rows) > e_old else None
        block = ob if fresh is None else fresh if ob is None else _joined_block(ob, fresh)
        if block is None or store.cls in edited:
            block = edge_class_block(store, rows, offset, hessian_index)
        blocks.append(block)
        plan.append((store, e_old, len(rows) - e_old))
        if fresh is not None:
            for acc, part in zip(contributions, hessian_contributions(fresh, n)):
                acc += part
            for acc, part in zip(links, gauge_links(fresh)):
                acc += part
    if old_by_store:
        return None
    cat = [np.concatenate(c) if c else np.zeros(0, dtype=np.int64) for c in contributions]
    extension = old.pattern.extended(n, cat[0], cat[1], cat[2].astype(bool))
    if extension is None:
        return None
    if not _gauge_extension_ok(old, free_handles, *links):
        return build_structure(vertex_store, edge_stores)        # raises GaugeFreedomError, naming the vertices
    pattern, scatter_new = extension
    old_scatter = np.where(old.pattern.scatter == old.pattern.nnz, pattern.nnz, old.pattern.scatter)
    scatter = _interleave(old.blocks, plan, old_scatter, scatter_new, lambda w: w[0])
    pattern.scatter = scatter.astype(np.int32, copy=False)           # the positions' dtype, as built
    old_brows = np.where(old.gradient_rows == old.dimension, n, old.gradient_rows)
    gradient_rows = _interleave(old.blocks, plan, old_brows, cat[3], lambda w: w[1])
    return GraphStructure(
        dimension=n, handle_count=vertex_store.count, hessian_index=hessian_index, vertex_groups=groups,
        manifold=any(getattr(g.cls, 'oplus_jacobian_batch', None) is not None for g in groups),
        free_state_index=free_state_index,
        blocks=blocks, pattern=pattern, gradient_rows=gradient_rows)
