"""helpers.advanced — speed and research code, apart from the course.

The course (notebooks 00–21 and the exercises) never imports this package (``tests/test_layers.py``); the advanced
notebooks (22, 23) and ``benchmarks/`` do. It builds on the course modules:

- ``online_slam``: data association inside SLAM (the joint predicted density from the graph's factorisation,
  tentative landmarks and their confirmation, loop closure, Victoria Park online);
- ``hidden_ids``: DriveBot with the landmark ids hidden (``run_hidden_ids``, ``association_report``), and
  ``hidden_ids_support`` for notebook 22;
- ``incremental`` (with ``chain_factor`` and ``chain_kernel``): optimising after every addition with a factor kept
  between updates (iSAM2's relinearisation rule);
- ``fast_graph``: ``FastOptimizer``, the course's graph on a faster engine with GTSAM's LM schedule;
  ``drivebot_variants`` runs DriveBot with it (``run_fast``) and with the incremental smoother (``run_incremental``);
- ``jcbb_fast`` (with ``jcbb_kernel``): JCBB compiled with numba, for the front-end and ``benchmarks/jcbb.py``.
"""
