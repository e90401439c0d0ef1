"""Named errors of the graph optimiser."""

__all__ = ["GraphError", "GaugeFreedomError", "NonFiniteError"]


class GraphError(ValueError):
    """A graph that cannot be optimised as given (unknown/duplicate element, stale structure, ...)."""


class GaugeFreedomError(GraphError):
    """A connected component of free vertices has nothing fixed attached and no unary (prior-type) edge.

    Its Hessian block is singular (a global translation/rotation of the component leaves χ² unchanged).
    ``component`` holds the vertices of the first free component found, ``components`` all of them.
    """

    def __init__(self, message, components=()):
        super().__init__(message)
        self.components = [list(c) for c in components]
        self.component = self.components[0] if self.components else []


class NonFiniteError(GraphError):
    """An edge's error, χ² contribution or Jacobian is NaN or ±inf (a degenerate configuration, an overflowing
    estimate, or a model that returns NaN), so χ² or H cannot be trusted.

    ``edges`` holds the offending edge objects (all of them; the message names the first few by class and vertex
    ids). When the optimiser raises it, the vertices hold the last accepted state.
    """

    def __init__(self, message, edges=()):
        super().__init__(message)
        self.edges = list(edges)
