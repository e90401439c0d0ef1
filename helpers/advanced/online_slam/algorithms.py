"""The four L09 algorithms behind one name each, as the front-end calls them.

Every algorithm of ``helpers.association`` has the common interface ``algorithm(density, Y, **options) ->
Association`` (landmarks choose observations; ``idx[k]`` = observation column or −1). The names here:

    "nn"           Euclidean nearest neighbour (``nearest_neighbour``), one-to-one, gate ``max_distance`` in
                   measurement units — default n_σ·√trace(R): the sensor noise alone, the pose and map
                   uncertainty ignored (which is what makes NN fail after drift);
    "mahalanobis"  individually compatible nearest neighbour (``mahalanobis_nn``), χ²_d gate at n_σ;
    "ml"           maximum likelihood with the independence assumption (``maximum_likelihood``); new-landmark
                   likelihood ``alpha`` (default None: the χ² gate decides);
    "jcbb"         joint compatibility branch and bound (``jcbb``); node budget ``max_nodes`` (default 20 000).
"""
from __future__ import annotations

import math
import numbers

import numpy as np

from ...association.maximum_likelihood import maximum_likelihood
from ...association.nearest_neighbour import mahalanobis_nn, nearest_neighbour
from ...validation import integer
from ..jcbb_fast import jcbb

__all__ = ["ALGORITHMS", "check_algorithm", "check_options", "associate"]

ALGORITHMS = {"nn": nearest_neighbour, "mahalanobis": mahalanobis_nn, "ml": maximum_likelihood, "jcbb": jcbb}

_OPTIONS = {"nn": ("max_distance",), "mahalanobis": (), "ml": ("alpha",), "jcbb": ("max_nodes",)}
_DEFAULTS = {"jcbb": {"max_nodes": 20000}}


def check_algorithm(name, argument: str = "data_association") -> str:
    """``name`` if it is one of the algorithm names, else ValueError naming ``argument``."""
    if not isinstance(name, str) or name not in ALGORITHMS:
        raise ValueError(f"{argument} must be one of {sorted(ALGORITHMS)}, got {name!r}")
    return name


def _positive_or_none(what):
    """A check of an option that is a positive finite number or None, with the algorithm's own message."""
    def check(value, name):
        if value is None:
            return
        try:
            ok = not isinstance(value, bool) and isinstance(value, numbers.Real) and math.isfinite(value) and value > 0
        except OverflowError:                   # an int too large for a float
            ok = False
        if not ok:
            raise ValueError(f"{name} must be {what} or None, got {value!r}")
    return check


#: option → check(value, name): the checks (and messages) the algorithms themselves make when they run
_CHECKS = {"max_distance": _positive_or_none("a positive finite number"),
           "alpha": _positive_or_none("a positive finite likelihood"),
           "max_nodes": lambda value, name: integer(value, name, minimum=1, allow_none=True)}


def check_options(name, options) -> dict:
    """The options of algorithm ``name`` (its defaults completed), checked as the algorithm checks them when it
    runs: unknown keys and bad values raise ValueError naming ``algorithm_options`` and the option. The front-end
    calls it at construction, and so can any caller that wants bad options refused before a run starts."""
    check_algorithm(name)
    options = {} if options is None else options
    if not isinstance(options, dict):
        raise ValueError(f"algorithm_options must be a dict or None, got {type(options).__name__}")
    unknown = sorted((k for k in options if k not in _OPTIONS[name]), key=repr)
    if unknown:
        raise ValueError(f"algorithm_options: {unknown} are not options of {name!r} (it takes "
                         f"{list(_OPTIONS[name])}; n_sigma is the front-end's own argument)")
    for key, value in options.items():
        try:
            _CHECKS[key](value, key)
        except ValueError as err:
            raise ValueError(f"algorithm_options: {err}") from None
    return {**_DEFAULTS.get(name, {}), **options}


def associate(name, density, Y, n_sigma, options, R):
    """Run algorithm ``name`` on (density, Y) with the front-end's gate ``n_sigma``; R sets NN's default gate."""
    fn = ALGORITHMS[name]
    opts = dict(options)
    if name == "nn" and "max_distance" not in opts:
        opts["max_distance"] = n_sigma * math.sqrt(float(np.trace(R)))
    return fn(density, Y, n_sigma=n_sigma, **opts)
