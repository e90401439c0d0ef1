"""Execute the workbook's notebooks headless, in order.

    python tools/execute_notebooks.py --inplace [NOTEBOOK ...]     # refresh the stored outputs (nbval reference)
    python tools/execute_notebooks.py --output-dir build/notebooks  # run without touching the committed files

Every notebook runs with its own directory as the working directory, in a fresh kernel, so a run here
matches what nbval does. Without arguments all ``notebooks/[0-9]*.ipynb`` are executed in name order.
"""
from __future__ import annotations

import argparse
import pathlib
import sys
import time

import nbformat
from nbclient import NotebookClient

ROOT = pathlib.Path(__file__).resolve().parents[1]
#: The kernel's own log at ERROR: ipykernel 7 otherwise warns on every start that its local TCP sockets are not
#: encrypted (true of every local Jupyter kernel, and nothing a student can act on). Cell output, Python
#: warnings raised in cells and kernel errors are not affected.
KERNEL_ARGUMENTS = ["--IPKernelApp.log_level=ERROR"]


def _shown(path: pathlib.Path) -> str:
    """A path relative to the workbook when it is inside it, else as given (copies elsewhere work too)."""
    try:
        return str(path.resolve().relative_to(ROOT))
    except ValueError:
        return str(path)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("notebooks", nargs="*", type=pathlib.Path)
    where = parser.add_mutually_exclusive_group(required=True)
    where.add_argument("--inplace", action="store_true", help="overwrite each notebook with its executed version")
    where.add_argument("--output-dir", type=pathlib.Path, help="write executed copies here")
    parser.add_argument("--timeout", type=int, default=600, help="per-cell timeout in seconds")
    args = parser.parse_args(argv)

    paths = args.notebooks or sorted((ROOT / "notebooks").glob("[0-9]*.ipynb"))
    if not paths:
        print("no notebooks found", file=sys.stderr)
        return 1
    for k, path in enumerate(paths, start=1):
        path = path.resolve()
        print(f"[{k}/{len(paths)}] {_shown(path)} ...", end=" ", flush=True)
        start = time.perf_counter()
        nb = nbformat.read(path, as_version=4)
        # store_widget_state=False: the widget models of an exploration (random ids) stay out of the notebook's
        # metadata; an opened notebook shows the knobs' text and the stored figure until it is run
        client = NotebookClient(nb, timeout=args.timeout, kernel_name="python3", extra_arguments=KERNEL_ARGUMENTS,
                                resources={"metadata": {"path": str(path.parent)}}, store_widget_state=False)
        client.execute()
        target = path if args.inplace else ((ROOT / args.output_dir).resolve() / path.name)
        target.parent.mkdir(parents=True, exist_ok=True)
        nbformat.write(nb, target)
        print(f"{time.perf_counter() - start:.1f} s -> {_shown(target)}", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
