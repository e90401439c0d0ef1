"""Linearisation: evaluate every edge class at the current estimates, whiten, and assemble χ², H and b.

Per edge class (one ``EdgeClassBlock``, no Python loop over edges): gather the slot states, call the class's
``evaluate``, multiply the Jacobians of slots whose vertex class has a non-additive ⊞ by M = ∂(x ⊞ δ)/∂δ, whiten
(ẽ = W e, J̃_k = W J_k; elementwise when W is diagonal), then χ² = Σ‖ẽ‖², b_k = J̃_kᵀ ẽ, H_kl = J̃_kᵀ J̃_l.
The values are added into H's CSC data and b at the positions ``structure`` computed (``batched.scatter_jtj`` /
``scatter_jte``; ``linearise_reference`` forms the products first and sums them with ``np.bincount``).

``FreeState`` is the free state vector X as the algorithms see it: read it, write it back, step it by ⊞, and
evaluate χ² or the whole linear system at it.

Non-finite values. Every model output is shape-checked (GraphError naming the class); ``FreeState.chi2`` /
``linearise`` and ``total_chi2`` raise ``NonFiniteError`` when χ², H or b is NaN or inf, naming the offending
edges (found by a second, per-edge pass that only runs on that error path).
"""

from dataclasses import dataclass

import numpy as np

from ...graph.edge import check_model_output
from ...graph.elements import nonfinite_error, total_chi2
from ...graph.optimizer import _check_oplus_output
from .batched import (batched_jte, batched_jtj, plain_copy, plain_zeros, scatter_jte, scatter_jtj, scatter_jtj_upper,
                      whitened_jacobians)

__all__ = ["LinearSystem", "FreeState", "whitened_blocks", "oplus_jacobians", "chi2_at", "linearise",
           "linearise_reference", "total_chi2", "nonfinite_error"]


@dataclass(frozen=True)
class LinearSystem:
    """H (upper-triangle CSC data on the structure's pattern), b and χ² at one state."""

    hessian_data: np.ndarray
    gradient: np.ndarray
    chi2: float


_NO_OPLUS = np.zeros((0, 1, 1))               # whitened_jacobians' "no ⊞ Jacobian" (M = I)
_NO_HANDLES = np.zeros(0, dtype=np.int64)


def oplus_jacobians(structure, estimates):
    """Per dimension d: (handles, d, d) array of ∂(x ⊞ δ)/∂δ (identity for additive vertex classes)."""
    out = {}
    for group in structure.vertex_groups:
        if group.cls.oplus_jacobian_batch is None:
            continue
        d = group.state_index.shape[1]
        if d not in out:
            out[d] = np.broadcast_to(np.eye(d), (structure.handle_count, d, d)).copy()
        out[d][group.handles] = group.cls.oplus_jacobian_batch(estimates[group.state_index])
    return out


def whitened_blocks(structure, estimates, jacobians):
    """Per edge class: (block, whitened errors (E, m), whitened Jacobians [(E, m, d_k)] or None)."""
    out = []
    mjac = oplus_jacobians(structure, estimates) if (jacobians and structure.manifold) else None
    for blk in structure.blocks:
        states = [estimates[s] for s in blk.state_index]
        e, jac = blk.store.cls.evaluate(states, blk.measurements, blk.params, jacobians=jacobians)
        check_model_output(blk.store.cls, e, jac, blk.count, jacobians)
        if blk.diagonal_whitening:
            ew = blk.whitening * e
            w = blk.whitening[:, :, None]
        else:
            ew = batched_jte(blk.whitening_t, np.ascontiguousarray(e))
            w = blk.whitening
        jw = None
        if jac is not None:                 # J̃_k = W J_k M_k (M_k = I for an additive slot)
            jw = []
            for k, j in enumerate(jac):
                m = None if mjac is None else mjac.get(j.shape[2])
                jw.append(whitened_jacobians(j, _NO_OPLUS if m is None else m,
                                             _NO_HANDLES if m is None else blk.handles[:, k], w,
                                             blk.diagonal_whitening))
        out.append((blk, ew, jw))
    return out


def chi2_at(structure, estimates):
    """χ² of the structure's edges at ``estimates`` (no Jacobians)."""
    total = 0.0
    for _, ew, _ in whitened_blocks(structure, estimates, False):
        total += float(np.einsum("ei,ei->", ew, ew))
    return total


def linearise(structure, estimates):
    """The ``LinearSystem`` (H data, b, χ²) at ``estimates``: ``linearise_reference``'s products and sums, with
    each edge's H_kl and b_k added straight into H's CSC data and b (``scatter_jtj``, ``scatter_jte``: the same
    additions in the same order, so the result is bit-for-bit the reference's)."""
    n = structure.dimension
    if n == 0:
        return linearise_reference(structure, estimates)
    data = plain_zeros(structure.pattern.nnz + 1)               # the last bin collects fixed-vertex terms
    b = np.zeros(n + 1)
    chi2, th, tb = 0.0, 0, 0
    scatter, gradient_rows = structure.pattern.scatter, structure.gradient_rows
    for blk, ew, jw in whitened_blocks(structure, estimates, True):
        chi2 += float(np.einsum("ei,ei->", ew, ew))
        ew = np.ascontiguousarray(ew)
        for k in range(blk.store.slots):
            th = scatter_jtj_upper(jw[k], scatter, th, data)
            for l in range(k + 1, blk.store.slots):
                th = scatter_jtj(jw[k], jw[l], False, scatter, th, data)
            tb = scatter_jte(jw[k], ew, gradient_rows, tb, b)
    return LinearSystem(data[:-1], b[:-1], chi2)


def linearise_reference(structure, estimates):
    """The ``LinearSystem`` (H data, b, χ²) at ``estimates``, in two plain steps: every edge's products
    J̃_kᵀ J̃_l and J̃_kᵀ ẽ, then their sums per entry of H and b with ``np.bincount``."""
    n = structure.dimension
    hvals, bvals = [], []
    chi2 = 0.0
    for blk, ew, jw in whitened_blocks(structure, estimates, True):
        chi2 += float(np.einsum("ei,ei->", ew, ew))
        nv = blk.store.slots
        for k in range(nv):
            jk = jw[k]
            for l in range(k, nv):
                hvals.append(batched_jtj(jk, jw[l], k == l).ravel())
            bvals.append(batched_jte(jk, ew).ravel())
    if n == 0:
        return LinearSystem(np.zeros(0), np.zeros(0), chi2)
    data = structure.pattern.assemble(np.concatenate(hvals) if hvals else np.zeros(0))
    b = np.bincount(structure.gradient_rows, weights=np.concatenate(bvals) if bvals else None, minlength=n + 1)[:n]
    return LinearSystem(data, b, chi2)


def nonfinite_edges(structure, estimates, jacobians):
    """The edges of a built structure whose whitened χ² term (or, with ``jacobians``, a whitened Jacobian) is not
    finite at ``estimates``, in block order (the per-edge pass behind NonFiniteError's message)."""
    bad = []
    for blk, ew, jw in whitened_blocks(structure, estimates, jacobians):
        mask = ~np.isfinite(np.einsum("ei,ei->e", ew, ew))
        for j in jw or ():
            mask |= ~np.isfinite(j).all(axis=(1, 2))
        bad.extend(blk.store.objects[r] for r in blk.rows[mask])
    return bad


class FreeState:
    """The free state vector X of a built structure over the graph's estimate storage.

    ``get()`` copies X out, ``set(x)`` writes it back, ``retract(dx)`` steps X ← X ⊞ (−dx) per vertex class;
    ``chi2()`` and ``linearise()`` evaluate at the current X; ``solve(system, damping)`` returns
    dX = (H + damping·I)⁻¹ b (NaN when not positive definite) with the graph's LDLᵀ solver.
    """

    def __init__(self, structure, estimates, solver, vertex_objects=None):
        self.structure = structure
        self._estimates = estimates  # GrowableArray (its buffer is re-read: it is replaced when it grows)
        self.solver = solver
        self._objects = vertex_objects  # vertex object per handle (only to name vertices in errors), or None

    @property
    def pattern(self):
        return self.structure.pattern

    def get(self):
        return self._estimates.buffer[self.structure.free_state_index].copy()

    def set(self, x):
        self._estimates.buffer[self.structure.free_state_index] = x

    def retract(self, dx):
        vx = self._estimates.buffer
        for group in self.structure.vertex_groups:
            moved = group.cls.oplus_batch(vx[group.state_index], -dx[group.hessian_rows])
            _check_oplus_output(group, moved, self._objects)
            vx[group.state_index] = moved

    def chi2(self, what="chi2"):
        """χ² at X; NonFiniteError (``what`` says where) naming the edges when it is NaN or inf."""
        value = chi2_at(self.structure, self._estimates.buffer)
        if not np.isfinite(value):
            raise nonfinite_error(what, nonfinite_edges(self.structure, self._estimates.buffer, False))
        return value

    def linearise(self, what="linearise"):
        """(H, b, χ²) at X; NonFiniteError (``what`` says where) naming the edges when any of them is not finite."""
        system = linearise(self.structure, self._estimates.buffer)
        if not (np.isfinite(system.chi2) and np.isfinite(system.gradient).all()
                and np.isfinite(system.hessian_data).all()):
            raise nonfinite_error(what, nonfinite_edges(self.structure, self._estimates.buffer, True))
        return system

    def solve_factored(self, system):
        """dX = H⁻¹ b with the solver's current factorisation, which the caller knows to be that of H."""
        return self.solver.solve(system.gradient)

    def solve(self, system, damping=None):
        """dX = (H + damping·I)⁻¹ b; ``damping=None``: undamped (H⁻¹ b)."""
        pattern = self.structure.pattern
        if damping is None:
            return self.solver.factor(pattern, system.hessian_data).solve(system.gradient)
        damped = plain_copy(system.hessian_data)
        damped[pattern.diag_pos] += damping
        return self.solver.factor(pattern, damped, damping=damping).solve(system.gradient)
