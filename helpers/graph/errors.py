"""Named errors of the graph optimiser."""
from __future__ import annotations

__all__ = ["GraphError", "GaugeFreedomError", "NonFiniteError"]


class GraphError(ValueError):
    """A graph that cannot be optimised as given (unknown/duplicate element, stale structure, ...)."""


class GaugeFreedomError(GraphError):
    """A connected component of free vertices has nothing fixed attached and no unary (prior) edge, so its Hessian
    block is singular. ``component`` holds the vertices of the first free component found, ``components`` all."""

    def __init__(self, message: str, components: list = ()) -> None:
        super().__init__(message)
        self.components = [list(c) for c in components]
        self.component = self.components[0] if self.components else []


class NonFiniteError(GraphError):
    """An edge's error, χ² term or Jacobian is NaN or ±inf, so χ² or H cannot be trusted. ``edges`` holds the
    offending edges; when the optimiser raises it, the vertices hold the last accepted state."""

    def __init__(self, message: str, edges: list = ()) -> None:
        super().__init__(message)
        self.edges = list(edges)
