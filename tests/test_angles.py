"""The shared angle wraps: wrap_angle (the graph's) and wrap_angle_mod (the simulator's form, bit for bit)."""
import math

import numpy as np

from helpers.graph import wrap_angle_mod


def test_wrap_angle_mod_keeps_the_simulator_form_bit_for_bit():
    rng = np.random.default_rng(8)
    values = rng.uniform(-10, 10, 5000)
    assert wrap_angle_mod(values).tobytes() == ((values + np.pi) % (2.0 * np.pi) - np.pi).tobytes()
    for v in values[:200].tolist():
        out = wrap_angle_mod(v)
        assert type(out) is float and out == (v + math.pi) % (2.0 * math.pi) - math.pi
    from helpers.drivebot import simulator
    assert simulator.wrap_angle_mod is wrap_angle_mod
