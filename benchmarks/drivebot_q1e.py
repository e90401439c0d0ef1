"""DriveBot timing: q1_e optimising at every step (goal ≤ 10 s for the whole run) and the cost of building
the 5273-step graphs (q1_d, q2_c, q3_a) without their optimisations.

    .venv/bin/python benchmarks/drivebot_q1e.py
"""
import time

import numpy as np

from helpers.drivebot import run_question


def main(repeats: int = 3) -> None:
    run_question("q1_e", seed=1, enable_compass=True, maximum_step_number=30)  # load the compiled kernels
    print("q1_e, optimisation period 1, whole run (simulation + graph building + 324 optimisations)")
    print(f"{'case':<16}{'best (s)':>10}{'median (s)':>12}{'opt. total (s)':>16}{'median/step (ms)':>18}"
          f"{'max/step (ms)':>15}{'mean LM it.':>13}")
    for label, kw in (("GPS only", {}), ("GPS + compass", {"enable_compass": True})):
        runs = [run_question("q1_e", seed=0, **kw) for _ in range(repeats)]
        totals = np.array([r.run_time for r in runs])
        best = runs[int(np.argmin(totals))]
        ot = best.optimization_times
        print(f"{label:<16}{totals.min():>10.2f}{np.median(totals):>12.2f}{np.nansum(ot):>16.2f}"
              f"{1e3 * np.nanmedian(ot):>18.2f}{1e3 * np.nanmax(ot):>15.1f}"
              f"{best.optimization_iterations.mean():>13.1f}")
        assert best.n_steps == 324
    print("\n5273-step runs: whole run and simulation + graph building (whole run − optimisation time)")
    for q in ("q1_d", "q2_c", "q3_a"):
        t0 = time.perf_counter()
        r = run_question(q, seed=0)
        total = time.perf_counter() - t0
        opt = np.nansum(r.optimization_times)
        print(f"{q}: N = {r.n_steps}, whole {total:.2f} s, optimisations {opt:.2f} s "
              f"({int(np.isfinite(r.optimization_times).sum())} calls), build {total - opt:.2f} s")


if __name__ == "__main__":
    main()
