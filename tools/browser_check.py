"""The browser check of an exploration notebook (CI only): JupyterLab in headless Chromium, run all, move a slider,
and check that the figure changed.

    .venv/bin/python tools/browser_check.py notebooks/05_snn_demo.ipynb [--timeout 600] [--artifacts DIR]

What it does, in order (Linux; every step has a time limit, and everything it started is stopped on every exit):
1. Debian's Chromium (/usr/bin/chromium): when missing it is installed with apt-get (root only, with CI=true or
   --install), otherwise the check stops with the command to run. No chromedriver is needed: Playwright drives
   Chromium over the DevTools protocol.
2. Playwright, pinned below (PINS), in .venv (the script runs itself with .venv's Python): installed from PyPI
   with CI=true or --install. It stays out of environment.txt, so students never download it (its wheel carries
   a 50 MB Node runtime); no browser is downloaded (Playwright is pointed at Debian's Chromium).
3. JupyterLab from .venv on a free 127.0.0.1 port with a random token, its settings, workspaces and runtime files
   in a temporary folder that also holds a copy of the notebook (outputs and widget state stripped).
4. Headless Chromium opens the copy, runs all cells (JupyterLab's own command) and waits for the kernel; a cell
   error fails the check. It then presses the arrow keys on the first slider's handle (--moves times, right then
   left) and after each waits for helpers.explore's report under the knobs ("redraw N: T ms") and for the
   figure (the last image in that cell's output) to change. A redraw that leaves the image unchanged fails (the
   draw ignores the knob), and so does an error reported there.
--timeout counts from after the installs (apt-get and pip have their own limits, never cut short mid-install).
Exit status 0: the figure changed; 1: the check failed (the message says how); 2: the environment is missing
something (the message says what to run).
"""
from __future__ import annotations

import argparse
import json
import os
import pathlib
import secrets
import shutil
import signal
import socket
import subprocess
import sys
import tempfile
import time
import urllib.request

ROOT = pathlib.Path(__file__).resolve().parents[1]
VENV_PYTHON = ROOT / ".venv" / ("Scripts/python.exe" if os.name == "nt" else "bin/python")
CHROMIUM = pathlib.Path("/usr/bin/chromium")
#: CI-only packages (Linux wheels): Playwright and its one dependency. Not in environment.txt on purpose.
PINS = ("playwright==1.65.2", "greenlet==3.5.6")
#: JupyterLab settings for the run: no news or update checks (no network), no pop-up notifications.
LAB_SETTINGS = {"@jupyterlab/apputils-extension/notification.jupyterlab-settings":
                {"fetchNews": "false", "checkForUpdates": False, "doNotDisturbMode": True}}
#: true once the kernel is idle and every code cell has run, or one failed (run-all then stops)
JS_DONE = """() => { const w = window.jupyterapp && window.jupyterapp.shell.currentWidget;
  const k = w && w.sessionContext && w.sessionContext.session && w.sessionContext.session.kernel;
  if (!k || k.status !== 'idle') return false;
  const cells = w.content.widgets.filter(c => c.model.type === 'code');
  const failed = cells.some(c => c.model.outputs.toJSON().some(o => o.output_type === 'error'));
  return failed || cells.every(c => c.model.executionCount !== null || !c.model.sharedModel.getSource().trim()); }"""
JS_ERRORS = """() => window.jupyterapp.shell.currentWidget.content.widgets.flatMap(c => c.model.type !== 'code' ? [] :
  c.model.outputs.toJSON().filter(o => o.output_type === 'error').map(o => o.ename + ': ' + o.evalue))"""


class CheckFailed(Exception):
    """The check ran and failed (exit 1)."""


class Missing(Exception):
    """The environment lacks something the check needs (exit 2)."""


def log(text: str) -> None:
    print(f"browser check: {text}", flush=True)


def may_install(args) -> bool:
    return args.install or os.environ.get("CI", "").lower() in ("1", "true", "yes")


def ensure_chromium(args) -> None:
    if CHROMIUM.exists():
        return
    if not (may_install(args) and hasattr(os, "geteuid") and os.geteuid() == 0 and shutil.which("apt-get")):
        raise Missing(f"{CHROMIUM} is missing: install Debian's Chromium (as root: apt-get install -y "
                      "--no-install-recommends chromium), or run this check as root with CI=true or --install")
    t0 = time.perf_counter()
    cmd = ["apt-get", "install", "-y", "-q", "--no-install-recommends", "chromium"]
    env = dict(os.environ, DEBIAN_FRONTEND="noninteractive")
    if subprocess.run(cmd, env=env, timeout=900).returncode != 0:   # a stale package list: update, then once more
        subprocess.run(["apt-get", "update", "-q"], env=env, timeout=300, check=True)
        subprocess.run(cmd, env=env, timeout=900, check=True)
    log(f"installed Debian's chromium in {time.perf_counter() - t0:.0f} s")


def ensure_playwright(args) -> None:
    try:
        import playwright.sync_api  # noqa: F401
        return
    except ImportError:
        if not may_install(args):
            raise Missing(f"Playwright is not installed: {sys.executable} -m pip install {' '.join(PINS)} "
                          "(or run with CI=true or --install)") from None
    t0 = time.perf_counter()
    subprocess.run([sys.executable, "-m", "pip", "install", "--quiet", "--only-binary=:all:", *PINS],
                   timeout=600, check=True)
    log(f"installed {', '.join(PINS)} in {time.perf_counter() - t0:.0f} s")


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def prepare(notebook: pathlib.Path, tmp: pathlib.Path) -> str:
    """The notebook copied into tmp/work without outputs and widget state, and the lab's settings; its name."""
    nb = json.loads(notebook.read_text(encoding="utf-8"))
    nb.get("metadata", {}).pop("widgets", None)
    for cell in nb["cells"]:
        if cell["cell_type"] == "code":
            cell["outputs"], cell["execution_count"] = [], None
    (tmp / "work").mkdir()
    (tmp / "work" / notebook.name).write_text(json.dumps(nb, indent=1), encoding="utf-8")
    for name, values in LAB_SETTINGS.items():
        path = tmp / "settings" / name
        path.parent.mkdir(parents=True)
        path.write_text(json.dumps(values), encoding="utf-8")
    return notebook.name


def start_lab(tmp: pathlib.Path, port: int, token: str, deadline: float) -> subprocess.Popen:
    env = dict(os.environ, JUPYTER_PLATFORM_DIRS="1", JUPYTER_CONFIG_DIR=str(tmp / "config"),
               JUPYTER_RUNTIME_DIR=str(tmp / "runtime"), JUPYTERLAB_SETTINGS_DIR=str(tmp / "settings"),
               JUPYTERLAB_WORKSPACES_DIR=str(tmp / "workspaces"), PYDEVD_DISABLE_FILE_VALIDATION="1")
    cmd = [str(VENV_PYTHON), "-m", "jupyterlab", "--no-browser", "--ip=127.0.0.1", f"--port={port}",
           "--ServerApp.port_retries=0", f"--IdentityProvider.token={token}", f"--ServerApp.root_dir={tmp / 'work'}",
           "--LabApp.expose_app_in_browser=True", "--LabApp.extension_manager=readonly"]
    if hasattr(os, "geteuid") and os.geteuid() == 0:
        cmd.append("--allow-root")                  # CI runs as root
    with open(tmp / "lab.log", "wb") as out:   # the child keeps its own descriptor
        lab = subprocess.Popen(cmd, stdout=out, stderr=subprocess.STDOUT, env=env, start_new_session=True)
    url = f"http://127.0.0.1:{port}/api/status?token={token}"
    while time.monotonic() < deadline:
        if lab.poll() is not None:
            raise CheckFailed(f"JupyterLab exited with status {lab.returncode}:\n{tail(tmp / 'lab.log')}")
        try:
            with urllib.request.urlopen(url, timeout=5) as reply:
                if reply.status == 200:
                    return lab
        except OSError:
            time.sleep(0.5)
    raise CheckFailed(f"JupyterLab did not answer in time:\n{tail(tmp / 'lab.log')}")


def tail(path: pathlib.Path, lines: int = 20) -> str:
    try:
        return "\n".join(path.read_text(encoding="utf-8", errors="replace").splitlines()[-lines:])
    except OSError:
        return "(no log)"


def stop_lab(lab: subprocess.Popen, port: int, token: str) -> None:
    """Shut JupyterLab down (its kernels too); then end its whole process group, whatever is left."""
    try:
        request = urllib.request.Request(f"http://127.0.0.1:{port}/api/shutdown?token={token}", method="POST")
        urllib.request.urlopen(request, timeout=5).close()
        lab.wait(timeout=15)
    except (OSError, subprocess.TimeoutExpired):
        pass
    for sig, wait in ((signal.SIGTERM, 5), (signal.SIGKILL, 5)):
        try:
            os.killpg(lab.pid, sig)
        except ProcessLookupError:
            return
        end = time.monotonic() + wait
        while time.monotonic() < end:
            try:
                os.killpg(lab.pid, 0)
            except ProcessLookupError:
                return
            lab.poll()
            time.sleep(0.1)


def move(cell, image, handle, left, key: str, answer_within: float = 60) -> str:
    """Press ``key`` on the slider's handle; wait for the kernel's redraw (helpers.explore's "redraw N: T ms"
    under the knobs, within ``answer_within`` seconds) and for the figure to change; returns what happened (raises
    CheckFailed)."""
    readout, status = cell.locator(".widget-slider .widget-readout").first, cell.locator(".widget-html").last
    src, value, text = image.get_attribute("src"), readout.inner_text(), status.inner_text()
    t0 = time.perf_counter()
    handle.press(key)
    while status.inner_text() == text:                  # the kernel has not answered yet
        if time.perf_counter() - t0 > 5 and readout.inner_text() == value:
            raise CheckFailed(f"the slider did not move on {key} (its value stays {value})")
        if time.perf_counter() - t0 > answer_within:
            raise CheckFailed(f"the slider moved ({value} -> {readout.inner_text()}) but no redraw was reported "
                              f"within {answer_within:.0f} s (is the kernel alive? is it a helpers.explore figure?)")
        left()
        time.sleep(0.05)
    redrawn, text = time.perf_counter(), status.inner_text()
    if not text.startswith("redraw "):
        raise CheckFailed(f"the redraw failed: {text}")
    while image.get_attribute("src") == src:
        if time.perf_counter() - redrawn > 3:
            raise CheckFailed(f"the slider moved ({value} -> {readout.inner_text()}) and the kernel redrew ({text}), "
                              "but the figure is unchanged: the draw ignores the knob")
        time.sleep(0.05)
    return f"{value} -> {readout.inner_text()}: figure changed {time.perf_counter() - t0:.2f} s after {key} ({text})"


def drive(url: str, deadline: float, artifacts: pathlib.Path | None, moves: int = 1) -> str:
    """Open the notebook, run all, move the first slider ``moves`` times (right, left, ...); returns what changed
    (raises CheckFailed)."""
    from playwright.sync_api import Error, sync_playwright

    def left() -> float:
        if time.monotonic() >= deadline:
            raise CheckFailed("the time limit ran out")
        return 1000 * (deadline - time.monotonic())

    with sync_playwright() as pw:
        browser = pw.chromium.launch(executable_path=str(CHROMIUM), headless=True)
        try:
            page = browser.new_page(viewport={"width": 1400, "height": 1000})
            t0 = time.perf_counter()
            page.goto(url, timeout=left())
            page.wait_for_function("() => window.jupyterapp && window.jupyterapp.shell.currentWidget && "
                                   "window.jupyterapp.shell.currentWidget.sessionContext", timeout=left())
            page.evaluate("async () => { const w = window.jupyterapp.shell.currentWidget; await w.context.ready; "
                          "await w.sessionContext.ready; }")
            log(f"notebook open, kernel ready: {time.perf_counter() - t0:.1f} s")
            t0 = time.perf_counter()
            page.evaluate("() => { window.jupyterapp.commands.execute('notebook:run-all-cells'); }")  # no await
            try:
                page.wait_for_function(JS_DONE, timeout=left(), polling=250)
            except Error:
                raise CheckFailed(f"the cells were still running at the time limit "
                                  f"({time.perf_counter() - t0:.0f} s after run-all)") from None
            errors = page.evaluate(JS_ERRORS)
            if errors:
                raise CheckFailed(f"a cell failed: {errors[0]}")
            log(f"all cells ran: {time.perf_counter() - t0:.1f} s")
            cell = page.locator(".jp-CodeCell", has=page.locator(".widget-slider")).first
            handle = cell.locator(".widget-slider .noUi-handle").first
            image = cell.locator(".jp-OutputArea-output img").last
            try:
                handle.wait_for(timeout=min(left(), 30_000))
                image.wait_for(timeout=min(left(), 30_000))
            except Error:
                raise CheckFailed("no cell shows both a slider and a figure (is the exploration displayed?)") from None
            if artifacts:
                cell.screenshot(path=str(artifacts / "before.png"))
            handle.scroll_into_view_if_needed()
            handle.focus()
            at_max = float(handle.get_attribute("aria-valuenow")) >= float(handle.get_attribute("aria-valuemax"))
            keys = (["ArrowLeft", "ArrowRight"] if at_max else ["ArrowRight", "ArrowLeft"]) * moves
            results = [move(cell, image, handle, left, key) for key in keys[:moves]]
            if artifacts:
                cell.screenshot(path=str(artifacts / "after.png"))
            return "; ".join(results)
        finally:
            browser.close()


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("notebook", type=pathlib.Path)
    parser.add_argument("--timeout", type=float, default=600,
                        help="seconds for the check after the installs (default 600)")
    parser.add_argument("--install", action="store_true", help="install what is missing (implied by CI=true)")
    parser.add_argument("--artifacts", type=pathlib.Path, help="folder for the lab log and before/after pictures")
    parser.add_argument("--moves", type=int, default=1, help="slider moves, each checked (default 1)")
    args = parser.parse_args(argv)
    if pathlib.Path(sys.prefix).resolve() != VENV_PYTHON.parents[1].resolve() and VENV_PYTHON.exists():
        return subprocess.call([str(VENV_PYTHON), __file__, *(sys.argv[1:] if argv is None else argv)])  # .venv's
    start = time.monotonic()
    if not sys.platform.startswith("linux"):
        print("browser check: runs on Linux only (CI); skipped", file=sys.stderr)
        return 2
    signal.signal(signal.SIGTERM, lambda *_: sys.exit(143))   # a killed check still stops what it started
    lab = None
    tmp = pathlib.Path(tempfile.mkdtemp(prefix="browser-check-"))
    if args.artifacts:
        args.artifacts.mkdir(parents=True, exist_ok=True)
    try:
        if not args.notebook.is_file():
            raise Missing(f"no notebook {args.notebook}")
        ensure_chromium(args)                                # the installs have their own time limits
        ensure_playwright(args)
        deadline = time.monotonic() + args.timeout
        signal.signal(signal.SIGALRM, lambda *_: sys.exit("browser check: FAILED: the time limit ran out"))
        signal.alarm(int(args.timeout) + 60)                # a backstop: each step below has its own limit
        port, token = free_port(), secrets.token_hex(24)
        name = prepare(args.notebook.resolve(), tmp)
        lab = start_lab(tmp, port, token, deadline)
        log(f"JupyterLab up on port {port}: {time.monotonic() - start:.1f} s")
        try:
            result = drive(f"http://127.0.0.1:{port}/lab/tree/{name}?token={token}", deadline, args.artifacts,
                           max(1, args.moves))
        except Exception as err:  # Playwright's errors (a time-out waiting for the page, a closed browser)
            if isinstance(err, CheckFailed) or type(err).__module__.split(".")[0] != "playwright":
                raise
            raise CheckFailed(f"{type(err).__name__}: {str(err).splitlines()[0]}") from None
        log(f"PASSED: {result}")
        return 0
    except Missing as err:
        print(f"browser check: cannot run: {err}", file=sys.stderr)
        return 2
    except CheckFailed as err:
        print(f"browser check: FAILED: {err}", file=sys.stderr)
        return 1
    finally:
        signal.alarm(0)
        if lab is not None:
            stop_lab(lab, port, token)
        if args.artifacts and (tmp / "lab.log").exists():
            shutil.copy(tmp / "lab.log", args.artifacts / "lab.log")   # the folder exists (made above)
        shutil.rmtree(tmp, ignore_errors=True)
        log(f"stopped; {time.monotonic() - start:.1f} s in all")


if __name__ == "__main__":
    sys.exit(main())
