"""Merge verification with undo (``helpers.advanced.online_slam.verification``) on a hand-made out-and-back drive.

The robot drives along x past one landmark, scanning it three times (it is confirmed), drives on without scanning,
then backs up and scans the same place three times. ``closure_sigma`` is tiny, so on the way back the landmark is
untrusted: the re-observations start a tentative landmark, which the loop-closure stage merges into the old one on
a single pairing (``closure_support`` 1). In the *right* world the same landmark is seen again; in the *wrong* one a
second landmark ``offset`` metres away: close enough to be merged on one observation, too far for all three.
"""
import numpy as np
import pytest

from helpers.advanced.fast_graph import FastOptimizer
from helpers.advanced.online_slam import ConfirmationRules, OnlineFrontEnd, RangeBearingModel
from helpers.advanced.online_slam.tracks import CONFIRMED
from helpers.advanced.online_slam.verification import split_statistic
from helpers.graph import EdgeSE2, VertexSE2

R = np.diag([0.05, 0.01]) ** 2
ODO_INFO = np.linalg.inv(np.diag([0.002, 0.002, 0.0005]) ** 2)
RULES = ConfirmationRules(n_confirm=3, n_miss=3, max_age=10)


class OutAndBack:
    """Noise-free observations and odometry; ``back`` is the landmark seen on the way back."""

    def __init__(self, back, verify=True, **options):
        self.graph = FastOptimizer()
        first = VertexSE2(None, np.zeros(3), fixed=True)
        self.graph.add_vertex(first)
        self.pose, self.x = first, 0.0
        opts = dict(rules=RULES, closure_sigma=1e-3, closure_support=1, verify_merges=verify)
        opts.update(options)
        self.fe = OnlineFrontEnd(self.graph, RangeBearingModel(4.0, range_margin=0.5), "jcbb", **opts)
        self.fe.start(first)
        self.out, self.back = np.array([4.0, 1.0]), np.asarray(back, dtype=float)

    def move(self, step):
        z = np.array([step, 0.0, 0.0])
        v = VertexSE2(None, self.pose.estimate + z)
        self.graph.add_vertex(v)
        e = EdgeSE2([self.pose, v], measurement=z, information=ODO_INFO)
        self.graph.add_edge(e)
        self.fe.add_pose(e)
        self.pose, self.x = v, self.x + step

    def scan(self, landmark):
        d = landmark - np.array([self.x, 0.0])
        return self.fe.process_scan(np.array([[np.hypot(*d)], [np.arctan2(d[1], d[0])]]), R)

    def optimise(self):
        self.graph.initialize_optimization()
        self.graph.optimize(10, algorithm="lm-gtsam")
        return self.fe.refresh()

    def drive(self):
        for _ in range(3):
            self.move(0.5)
            self.scan(self.out)
        self.optimise()
        for _ in range(12):                      # on, out of range, without scanning
            self.move(0.5)
        self.optimise()
        for _ in range(12):
            self.move(-0.5)
        merged = []
        for _ in range(3):
            self.scan(self.back)
            merged += self.scan_result_merges()
            self.move(0.0)
        return merged

    def scan_result_merges(self):
        return [t.key for t in self.fe.tracks if t.alias_of >= 0]


def _consistent(world):
    """Every track's observations are edges to the vertex its status says, and nothing else is."""
    fe, g = world.fe, world.graph
    for t in fe.tracks:
        if t.status != CONFIRMED:
            continue
        root = fe.tracks[t.alias_of] if t.alias_of >= 0 else t
        assert root.vertex.graph is g
        assert t.vertex is root.vertex
    n_obs = sum(len(t.observations) for t in fe.tracks if t.status == CONFIRMED)
    n_rb = sum(1 for e in g.edges() if not isinstance(e, EdgeSE2))
    assert n_rb == n_obs
    for v in fe.confirmed_tracks():
        own = [o for t in fe.tracks if t.status == CONFIRMED and (t.key if t.alias_of < 0 else t.alias_of) == v.key
               for o in t.observations]
        assert v.vertex.number_of_edges() == len(own)


def test_a_right_merge_is_kept():
    w = OutAndBack(back=[4.0, 1.0])
    assert w.drive() == [1]
    assert w.optimise()
    assert w.fe.stats["merges_verified"] == 1 and w.fe.stats["merges_undone"] == 0
    (entry,) = w.fe.merge_log
    assert entry["track"] == 1 and entry["old"] == 0 and not entry["undone"] and entry["T"] < 1e-6
    assert w.fe.tracks[1].alias_of == 0
    assert list(w.fe.observation_assignment()) == [0] * 6
    _consistent(w)


def test_a_wrong_merge_is_undone_and_the_state_stays_consistent():
    w = OutAndBack(back=[4.0, 1.12])
    assert w.drive() == [1]                       # merged on a single pairing ...
    n_edges, n_vertices = w.graph.number_of_edges(), w.graph.number_of_vertices()
    assert w.optimise()                          # ... and refused after the optimisation
    (entry,) = w.fe.merge_log
    assert entry["undone"] and entry["T"] > w.fe._verify_gate and entry["edges"] == 3
    t, old = w.fe.tracks[1], w.fe.tracks[0]
    assert t.status == CONFIRMED and t.alias_of == -1 and t.vertex is not old.vertex
    assert [tr.key for tr in w.fe.confirmed_tracks()] == [0, 1]
    assert w.graph.number_of_edges() == n_edges and w.graph.number_of_vertices() == n_vertices + 1
    assert old.vertex.number_of_edges() == 3 and t.vertex.number_of_edges() == 3
    assert list(w.fe.observation_assignment()) == [0, 0, 0, 1, 1, 1]
    np.testing.assert_allclose(t.vertex.estimate, [4.0, 1.12], atol=1e-6)   # re-optimised
    np.testing.assert_allclose(old.vertex.estimate, [4.0, 1.0], atol=1e-6)
    assert any(t is f for f in w.fe._factorised)                           # the refresh that followed sees it
    _consistent(w)


def test_without_verification_the_wrong_merge_stays():
    w = OutAndBack(back=[4.0, 1.12], verify=False)
    assert w.drive() == [1]
    assert w.optimise()
    assert w.fe.merge_log == [] and w.fe.tracks[1].alias_of == 0
    assert list(w.fe.observation_assignment()) == [0] * 6


def test_a_merge_that_cannot_be_verified_is_left_as_it_was():
    w = OutAndBack(back=[4.0, 1.12])
    w.drive()
    w.fe._scan_firsts, w.fe._scan_poses = [0], [w.fe._scan_poses[0]]   # the poses of the scans are lost
    edges = w.graph.number_of_edges()
    assert w.optimise()
    assert w.fe.stats["merges_unverified"] == 1 and w.fe.merge_log == []
    assert w.fe.tracks[1].alias_of == 0 and w.graph.number_of_edges() == edges
    _consistent(w)


def test_split_statistic_needs_edges_of_the_landmark():
    w = OutAndBack(back=[4.0, 1.0])
    w.drive()
    w.optimise()
    other = w.fe.tracks[0].vertex
    odometry = [e for e in w.graph.edges() if isinstance(e, EdgeSE2)][:1]
    with pytest.raises(ValueError, match="edges"):
        split_statistic(odometry, other, lambda vs: np.zeros((9, 9)))


@pytest.mark.parametrize("name, value", [("verify_merges", "yes"), ("verify_merges", 1), ("verify_n_sigma", 0.0),
                                         ("verify_n_sigma", -1.0), ("verify_n_sigma", float("nan")),
                                         ("verify_n_sigma", 40.0), ("verify_iterations", 0),
                                         ("verify_iterations", 2.5)])
def test_bad_verification_options_name_the_argument(name, value):
    g = FastOptimizer()
    with pytest.raises(ValueError, match=name):
        OnlineFrontEnd(g, RangeBearingModel(4.0), "jcbb", **{name: value})


def test_run_hidden_ids_passes_the_verification_options_on():
    from helpers.advanced.hidden_ids import run_hidden_ids
    with pytest.raises(ValueError, match="verify_merges"):
        run_hidden_ids("q2_b", data_association="jcbb", verify_merges="yes")
