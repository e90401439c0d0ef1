"""Named errors of the graph optimiser."""

__all__ = ["GraphError", "GaugeFreedomError"]


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
