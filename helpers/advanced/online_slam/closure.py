"""Loop closure in the front-end: which candidates the tracking stage may use, and what becomes of tentative
landmarks that reach confirmation (steps 3–4 of ``frontend``'s docstring).

A landmark whose position relative to the vehicle is known only to more than ``closure_sigma`` metres (not seen
for long: a loop closure) is *untrusted*: it is never paired with a raw observation, because inside so wide a gate
a spurious detection is as likely as the landmark. Instead, tentative landmarks — consistent over ``n_confirm``
observations, so not clutter — are offered to it:

- ``_merge_duplicates``: a tentative landmark that duplicates a *trusted* confirmed landmark (it was started while
  that landmark was untrusted, and an optimisation has since pulled the map together) is merged into it, by the
  landmark-space test d² = (m_t − m_l)ᵀ S⁻¹ (m_t − m_l) ≤ χ²_2, S = Σ_tt + Σ_ll − Σ_tl − Σ_lt;
- ``_closure_stage``: the current observations of the tentative landmarks confirmable in this scan are associated,
  by the chosen algorithm, with the untrusted candidates. An unambiguous pairing, with at least
  ``closure_support`` pairings in all (a constellation: one pairing alone carries no joint evidence), merges the
  tentative landmark into the old one; one individually compatible with an old landmark but not merged waits (at
  most ``closure_patience`` scans); one compatible with none becomes a new landmark.

A merged track keeps its window entry until the next refresh and stands for the old landmark in the tracking stage
(``_tracking_candidates`` then leaves out whichever of the two is redundant).
"""
from __future__ import annotations

import numpy as np

from .tracks import CONFIRMED, TENTATIVE

__all__ = ["LoopClosure"]


class LoopClosure:
    """Mixin of ``OnlineFrontEnd`` (it supplies rules, the algorithm, stats and the track decisions)."""

    def _tracking_candidates(self, cands, untrusted):
        """Indices of the candidates the tracking stage uses: the trusted ones, without a merged track whose old
        landmark is itself a trusted candidate (the two are one vertex)."""
        trusted = np.flatnonzero(~untrusted).tolist()
        roots = {cands[i].key for i in trusted if cands[i].alias_of < 0}
        return np.array([i for i in trusted if cands[i].alias_of not in roots], dtype=np.int64)

    def _merge_duplicates(self, confirmable, cands, trusted, untrusted, sig_v, means, scan, edges, result):
        """Tentative landmarks with ``n_confirm`` observations that duplicate a *trusted* confirmed landmark (one
        that was untrusted when they were started, and has since been pulled in by an optimisation) are merged
        into it: d² = (m_t − m_l)ᵀ S⁻¹ (m_t − m_l) ≤ χ²_2 with S = Σ_tt + Σ_ll − Σ_tl − Σ_lt from the joint state
        covariance. Returns the confirmable (track, column) pairs that remain for the loop-closure stage."""
        trusted = trusted.tolist()
        todo = [i for i in trusted if cands[i].status == TENTATIVE and cands[i].hits >= self.rules.n_confirm]
        if not todo:
            return confirmable
        olds = [i for i in trusted if cands[i].status == CONFIRMED and cands[i].alias_of < 0]
        if not olds:
            return confirmable
        ld = self.model.landmark_dimension
        merged = set()
        for i in todo:
            rows_i = 3 + ld * i + np.arange(ld)
            hits = []
            for l in olds:
                rows_l = 3 + ld * l + np.arange(ld)
                S = (sig_v[np.ix_(rows_i, rows_i)] + sig_v[np.ix_(rows_l, rows_l)] - sig_v[np.ix_(rows_i, rows_l)]
                     - sig_v[np.ix_(rows_l, rows_i)])
                nu = means[i] - means[l]
                if nu @ np.linalg.solve(S, nu) <= self._ic_gate:
                    hits.append(l)
            if len(hits) == 1:
                self._merge(cands[i], cands[hits[0]], scan, edges, result)
                merged.add(cands[i].key)
        return [(t, j) for t, j in confirmable if t.key not in merged]

    def _closure_stage(self, confirmable, closure, scan, edges, result):
        """Step 4 of the module docstring for the tentative landmarks that reached confirmation in this scan."""
        if not confirmable:
            return
        untrusted = np.zeros(0, dtype=np.int64) if closure is None else closure[4]
        if untrusted.size == 0:
            for t, _ in confirmable:
                self._confirm(t, scan, edges, result)
            return
        yu, C, Yu, Rgate, _, cands = closure
        cols = np.array([j for _, j in confirmable])
        idx, _, _, d2 = self._associate(yu, C, Yu[:, cols], Rgate, untrusted, [cands[i] for i in untrusted])
        if np.count_nonzero(idx >= 0) < self.closure_support:
            idx[:] = -1
        compatible = (d2 <= self._ic_gate).any(axis=0)     # the problem's individual distances, not recomputed
        for c, (t, _) in enumerate(confirmable):
            hit = np.flatnonzero(idx == c)
            if hit.size:
                self._merge(t, cands[untrusted[hit[0]]], scan, edges, result)
            elif compatible[c]:
                if t.postponed_since < 0:
                    t.postponed_since = scan
                    self.stats["postponements"] += 1
                result.postponed.append(t.key)
            else:
                self._confirm(t, scan, edges, result)
