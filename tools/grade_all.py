"""Grade a class: every submission zip in a folder, each in its own clean copy of the answer key's grading tree.

    python tools/grade_all.py SUBMISSIONS_DIR [--out DIR] [--jobs N] [--timeout S] [--timeout-test S] [--only EX ...]

Per submission (``<student id>.zip`` from ``make submission``):

1. the grading tree (tools/grading_tree.py: the student edition plus the answer key's hidden tests, grade.py and
   registry) is built ONCE per batch; each submission gets a copy of it;
2. only the student's work goes into that copy (tools/submission_files.py: the exercise targets' bodies and the
   helper functions the student added next to them, read as text); nothing else from the zip is used;
3. the answer key's ``tools/grade.py`` runs in the copy in its own process (tools/grade_guard.py: no file changed
   outside the copy's folder), output capped, with a time limit per check (60 s: a check that runs longer ends
   the run) and per run (600 s); after a run that ended early, the exercise of the check that was running scores
   0 with the reason ("time limit", or the crash), the exercises finished before it keep their results, and the
   others are graded in a new run;
4. scores per test group (tools/grading_tree.py): a group scores its points when all its checks pass; an exercise
   that hit a time limit, or could not be taken from the zip, scores 0 with the reason.

Writes ``OUT/grades.csv`` (student, points per exercise, total), ``OUT/feedback/<student>.txt`` (points per
exercise and group, every failed check with expected and actual values and its hint; checks of the hidden tests
are marked [hidden]) and ``OUT/answers/<student>.json`` (the written answers, for marking by hand). A file that is
not a zip, lacks a module file or does not parse gets a 0 with the reason for what it affects; the batch goes on.
Trust: the student's function bodies run in the grading process, as in any autograder; they cannot bring files,
but code that deliberately forges the grader's output from inside the process is not prevented here (Gradescope's
container, tools/gradescope.py, is the stronger sandbox).
"""
from __future__ import annotations

import argparse
import concurrent.futures
import csv
import json
import pathlib
import re
import shutil
import sys
import tempfile
import time

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parent))
import grading_tree  # noqa: E402
import student  # noqa: E402
import submission_files  # noqa: E402
from grading_tree import TEST_TIME_LIMIT, points_of  # noqa: E402

ROOT = student.ROOT
TIME_LIMIT = "time limit"


# ---------------------------------------------------------------------------------------------- one submission
def grade_submission(zip_path, grading_tree_dir, reg: dict, timeout: float = 600, only=None, root=ROOT,
                     with_answers: bool = True, test_limit: float = TEST_TIME_LIMIT) -> dict:
    """Grade one submission; {"student", "scores": {ex: points}, "total", "possible", "reasons": {ex: why it scored
    0}, "groups": {ex: score_groups()}, "answers": the written answers, "feedback": text, "seconds"}.
    Never raises for a bad zip. ``timeout``: one grading run (a new run follows only after a run that ended early);
    ``test_limit``: one check."""
    zip_path = pathlib.Path(zip_path)
    exercises = [ex for ex in reg["exercise"] if not only or ex["name"] in only]
    names = [ex["name"] for ex in exercises]
    files = {n: t for n, t in submission_files.exercise_files(reg, root).items() if n in names}
    reasons = {}
    try:
        sources, problems = submission_files.read_modules(zip_path, sorted({r for t in files.values() for r, _ in t}))
    except ValueError as err:
        sources, problems = None, {}
        reasons = {n: str(err) for n in names}
    (outcomes, failures), output, elapsed = ({}, {}), "", 0.0
    if sources is not None:
        for name, targets in files.items():
            bad = [problems[r] for r, _ in targets if r in problems]
            if bad:
                reasons[name] = "; ".join(dict.fromkeys(bad))
        limits = (timeout, test_limit)
        (outcomes, failures), output, elapsed = _grade_in_copy(zip_path, grading_tree_dir, sources, files, names,
                                                               reasons, limits, root)
    groups = {ex["name"]: grading_tree.score_groups(ex, outcomes, root, reasons.get(ex["name"]), failures)
              for ex in exercises}
    scores = {n: sum(g["score"] for g in groups[n]) for n in names}
    answers = submission_files.read_answers(zip_path, submission_files.answer_cells(root)) if with_answers else []
    result = {"student": zip_path.stem, "scores": scores, "total": sum(scores.values()),
              "possible": sum(points_of(ex) for ex in exercises), "reasons": reasons, "groups": groups,
              "answers": answers, "seconds": elapsed}
    result["feedback"] = feedback_text(result, exercises, output)
    result["feedback_public"] = feedback_text(result, exercises, output, public=True)
    return result


def _grade_in_copy(zip_path, grading_tree_dir, sources, files, names, reasons, limits, root) -> tuple:
    """Copy the grading tree, merge the student's work into it and run the grader on every exercise. When a run
    ends early (a check over its time limit, a kill at the submission's limit, a crash), the exercise of the check
    that was running scores 0 with the reason, the exercises it had finished keep their results, and the rest run
    again in a new process. Adds to ``reasons``; returns ((test outcomes, failure texts), output, seconds)."""
    timeout, test_limit = limits
    work = pathlib.Path(tempfile.mkdtemp(prefix="grade-%s-" % re.sub(r"\W", "_", zip_path.stem)[:40]))
    outcomes, failures, outputs = {}, {}, []
    try:
        tree = work / "tree"
        shutil.copytree(grading_tree_dir, tree, ignore=shutil.ignore_patterns("*.pyc", ".pytest_cache"))
        grading_tree.set_read_only(tree, False)
        for name, reason in submission_files.merge_submission(tree, sources, files, root).items():
            reasons.setdefault(name, reason)
        queue = [[n for n in names if n not in reasons]]
        start = time.perf_counter()
        while queue and queue[0]:
            group = queue.pop(0)
            text, progress, timed_out = grading_tree.run_grader(tree, group, timeout, test_limit)
            outputs.append(text.rstrip("\n"))
            outcomes.update(progress["outcomes"])
            failures.update(progress["failures"])
            for nodeid, failure in progress["failures"].items():         # stopped inside the process (Python code)
                if failure["text"].startswith(TIME_LIMIT):
                    reasons.setdefault(grading_tree.exercise_of(nodeid), "%s: the check %s ran longer than %g s" % (
                        TIME_LIMIT, nodeid.split("::")[-1], test_limit))
            if not progress["finished"]:
                rest = _after_an_early_end(group, progress, timed_out, limits, reasons)
                if rest:
                    outputs.append("(the run ended early: grading %s in a new run)" % ", ".join(rest))
                    queue.append(rest)
        return (outcomes, failures), "\n".join(outputs), time.perf_counter() - start
    finally:
        grading_tree.set_read_only(work, False)
        shutil.rmtree(work, ignore_errors=True)


def _after_an_early_end(group, progress, timed_out, limits, reasons) -> list:
    """After a run of ``group`` that ended before its report: give the running check's exercise its reason and
    return the exercises to run again (none when the run got nowhere: those get a reason too)."""
    timeout, test_limit = limits
    running = progress["running"]
    if running:
        name = grading_tree.exercise_of(running)
        if timed_out == "run":
            why = "%s: grading stopped after %.0f s, in the check %s" % (TIME_LIMIT, timeout, running)
        elif timed_out == "check" or progress["running_for"] >= 0.9 * test_limit:
            why = "%s: the check %s ran longer than %g s" % (TIME_LIMIT, running.split("::")[-1], test_limit)
        else:
            why = "the grading process died in the check %s (see the grader's report)" % running.split("::")[-1]
        reasons.setdefault(name, why)
    collected = progress["collected"]
    done = {n for n in group if any(grading_tree.exercise_of(c) == n for c in collected)
            and all(c in progress["outcomes"] for c in collected if grading_tree.exercise_of(c) == n)}
    rest = [n for n in group if n not in done and n not in reasons]
    if rest and (running or done):
        return rest
    for name in rest:
        reasons.setdefault(name, "%s: grading stopped after %.0f s" % (TIME_LIMIT, timeout) if timed_out == "run" else
                           "the grader reported nothing for it (it crashed; see the grader's report)")
    return []


def feedback_text(result: dict, exercises: list, output: str, public: bool = False) -> str:
    """The feedback: total, points per exercise and per group, reasons, written answers, then the grader's report
    of every failed check (the instructor's version, hidden checks marked [hidden]). ``public``: the version a
    student may see before the deadline: the public groups only, each failed one with its failed checks (given,
    expected, actual, hint), and no word of the hidden checks but their total points."""
    hidden = sum(g["points"] for n in result["groups"] for g in result["groups"][n] if g["hidden"])
    got = sum(g["score"] for n in result["groups"] for g in result["groups"][n] if g["hidden"])
    lines = ["student: %s" % result["student"]]
    lines += (["score of the public checks: %g of %g (the hidden checks, %g points, are graded after the deadline)"
               % (result["total"] - got, result["possible"] - hidden, hidden)] if public else
              ["score: %g of %g" % (result["total"], result["possible"])]) + [""]
    for ex in exercises:
        name = ex["name"]
        groups = [g for g in result["groups"].get(name, []) if not (public and g["hidden"])]
        reason = result["reasons"].get(name)
        lines.append("%-36s %g / %g%s" % (name, sum(g["score"] for g in groups), sum(g["points"] for g in groups),
                                          ("    " + reason) if reason else ""))
        for g in [] if reason else groups:
            failed = "   (%d of %d checks failed)" % (len(g["failed"]), len(g["tests"])) if g["failed"] else ""
            lines.append("    %s %4g / %-4g %s%s%s" % ("✗" if g["failed"] else "✓", g["score"], g["points"], g["title"],
                                                   " [hidden]" if g["hidden"] else "", failed))
            if public and g["failed"]:
                lines.append("        " + g["output"].replace("\n", "\n        "))
    answers = result.get("answers") or []
    if answers:
        n = {st: sum(a["status"] == st for a in answers) for st in ("answered", "unanswered", "missing")}
        lines += ["", "written answers (marked by hand): %d of %d answered, %d unanswered, %d not in the submission"
                  % (n["answered"], len(answers), n["unanswered"], n["missing"])]
    if output and not public:
        lines += ["", "--- the grader's report (%.0f s) ---" % result.get("seconds", 0.0), output.rstrip("\n")]
    return "\n".join(lines) + "\n"


# ---------------------------------------------------------------------------------------------- the batch
def write_results(out_dir: pathlib.Path, results: list, exercises: list) -> None:
    """grades.csv (one row per student: points per exercise, total, written answers given; a last row "(max)"),
    feedback/ (the instructor's), feedback-public/ (what a student may see before the deadline) and answers/."""
    out_dir.mkdir(parents=True, exist_ok=True)
    (out_dir / "feedback").mkdir(exist_ok=True)
    (out_dir / "feedback-public").mkdir(exist_ok=True)
    names = [ex["name"] for ex in exercises]
    with open(out_dir / "grades.csv", "w", newline="", encoding="utf-8") as fh:
        writer = csv.writer(fh)
        writer.writerow(["student"] + names + ["total", "written answers"])
        for r in sorted(results, key=lambda r: r["student"]):
            answered = sum(a["status"] == "answered" for a in r.get("answers") or [])
            writer.writerow([r["student"]] + ["%g" % r["scores"][n] for n in names] + ["%g" % r["total"], answered])
        n_answers = max((len(r.get("answers") or []) for r in results), default=0)
        writer.writerow(["(max)"] + ["%g" % points_of(ex) for ex in exercises]
                        + ["%g" % sum(points_of(ex) for ex in exercises), n_answers])
    for r in results:
        (out_dir / "feedback" / ("%s.txt" % r["student"])).write_text(r["feedback"], encoding="utf-8")
        (out_dir / "feedback-public" / ("%s.txt" % r["student"])).write_text(r.get("feedback_public", r["feedback"]),
                                                                             encoding="utf-8")
        if r.get("answers"):
            (out_dir / "answers").mkdir(exist_ok=True)
            (out_dir / "answers" / ("%s.json" % r["student"])).write_text(
                json.dumps(r["answers"], indent=1, ensure_ascii=False) + "\n", encoding="utf-8")


def grade_all(submissions_dir, out_dir, jobs: int = 2, timeout_per_submission: float = 600, only=None,
              root=ROOT, progress=None, test_limit: float = TEST_TIME_LIMIT) -> list:
    """Grade every ``*.zip`` of ``submissions_dir`` (student id = the zip's stem) on ``jobs`` parallel workers;
    writes ``out_dir/grades.csv``, ``out_dir/feedback/<student>.txt`` and ``out_dir/answers/<student>.json``;
    returns the per-student results. ``progress(done, total, result)`` is called as each submission finishes."""
    submissions = sorted(pathlib.Path(submissions_dir).glob("*.zip"))
    out_dir = pathlib.Path(out_dir)
    reg = student.load_registry(root)
    if only:
        unknown = set(only) - {ex["name"] for ex in reg["exercise"]}
        if unknown:
            raise ValueError("unknown exercise(s): %s" % ", ".join(sorted(unknown)))
    exercises = [ex for ex in reg["exercise"] if not only or ex["name"] in only]
    names = [ex["name"] for ex in exercises]
    work = pathlib.Path(tempfile.mkdtemp(prefix="grade-all-"))
    results = []
    try:
        tree = grading_tree.build_grading_tree(work / "grading-tree", root)
        grading_tree.set_read_only(tree, True)

        def one(path):
            try:
                return grade_submission(path, tree, reg, timeout_per_submission, only, root, test_limit=test_limit)
            except Exception as err:    # noqa: BLE001  (one submission never stops the batch)
                return {"student": path.stem, "scores": {n: 0.0 for n in names}, "total": 0.0,
                        "possible": sum(points_of(ex) for ex in exercises),
                        "reasons": {n: "grading error" for n in names}, "groups": {}, "answers": [],
                        "feedback": "student: %s\nscore: 0\n\nthe grader could not grade this submission: %s: %s\n"
                                    % (path.stem, type(err).__name__, err)}

        with concurrent.futures.ThreadPoolExecutor(max_workers=max(1, jobs)) as pool:
            futures = [pool.submit(one, p) for p in submissions]
            for future in concurrent.futures.as_completed(futures):
                results.append(future.result())
                if progress:
                    progress(len(results), len(submissions), results[-1])
    finally:
        grading_tree.set_read_only(work, False)
        shutil.rmtree(work, ignore_errors=True)
    write_results(out_dir, results, exercises)
    return results


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("submissions", type=pathlib.Path)
    parser.add_argument("--out", type=pathlib.Path, default=None, help="default: SUBMISSIONS/graded")
    parser.add_argument("--jobs", type=int, default=2)
    parser.add_argument("--timeout", type=float, default=600, help="seconds per grading run of a submission")
    parser.add_argument("--timeout-test", type=float, default=TEST_TIME_LIMIT, help="seconds per check")
    parser.add_argument("--only", nargs="+", default=None, help="grade only these exercises")
    args = parser.parse_args(argv)
    if not args.submissions.is_dir():
        print("no folder %s" % args.submissions, file=sys.stderr)
        return 2
    out = args.out or args.submissions / "graded"
    start = time.perf_counter()

    def progress(done, total, result):
        width = 30
        bar = "#" * (width * done // max(total, 1))
        print("[%-*s] %d/%d  %-24s %g" % (width, bar, done, total, result["student"], result["total"]), flush=True)

    try:
        results = grade_all(args.submissions, out, args.jobs, args.timeout, args.only, progress=progress,
                            test_limit=args.timeout_test)
    except (ValueError, student.BuildError) as err:
        print("error: %s" % err, file=sys.stderr)
        return 2
    print("graded %d submissions in %.0f s: %s, %s" % (len(results), time.perf_counter() - start,
                                                       out / "grades.csv", out / "feedback"))
    return 0


if __name__ == "__main__":
    sys.exit(main())
