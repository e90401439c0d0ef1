"""Check that every pin of a lock file installs from binary wheels on each supported platform and Python.

    python tools/check_wheels.py                          # environment.txt on all 12 targets
    python tools/check_wheels.py environment-peers.txt    # the optional peers: reports where wheels exist
    python tools/check_wheels.py --target linux-aarch64   # one platform (all three Pythons)

For every target (platform × Python) the script evaluates each pin's environment marker *for that target*
(pip evaluates markers for the host it runs on, so this is done here), then asks pip to fetch exactly the
applicable pins as binary wheels for the target's tags::

    pip download --no-deps --only-binary=:all: --platform TAG [--platform TAG ...]
                 --python-version X.Y.Z --implementation cp --abi cpXY -d TMP -r PINS

Linux targets list their manylinux tags explicitly (pip does not expand ``manylinux_2_28`` to the older
``manylinux_2_17`` wheels it can also run). The downloaded wheels are deleted after each target. Exit status
0 means every applicable pin has a wheel on every checked target.
"""
import argparse
import pathlib
import re
import subprocess
import sys
import tempfile

try:
    from packaging.markers import Marker
    from packaging.requirements import Requirement
except ImportError:  # any Python with pip can run this check
    from pip._vendor.packaging.markers import Marker
    from pip._vendor.packaging.requirements import Requirement

ROOT = pathlib.Path(__file__).resolve().parents[1]

# glibc 2.17 … 2.28: Linux distributions from 2019 on (Debian 10, Ubuntu 18.10, RHEL 8) and newer.
_GLIBC = [f"manylinux_2_{m}" for m in range(28, 16, -1)]
PLATFORMS = {
    "windows-x86_64": {"tags": ["win_amd64"], "env": {"os_name": "nt", "sys_platform": "win32",
                                                     "platform_system": "Windows", "platform_machine": "AMD64"}},
    "macos-arm64": {"tags": ["macosx_14_0_arm64"], "env": {"os_name": "posix", "sys_platform": "darwin",
                                                          "platform_system": "Darwin", "platform_machine": "arm64"}},
    "linux-x86_64": {"tags": [f"{g}_x86_64" for g in _GLIBC] + ["manylinux2014_x86_64"],
                     "env": {"os_name": "posix", "sys_platform": "linux", "platform_system": "Linux",
                             "platform_machine": "x86_64"}},
    "linux-aarch64": {"tags": [f"{g}_aarch64" for g in _GLIBC] + ["manylinux2014_aarch64"],
                      "env": {"os_name": "posix", "sys_platform": "linux", "platform_system": "Linux",
                              "platform_machine": "aarch64"}},
}
PYTHONS = ["3.11.5", "3.12.0", "3.13.0"]


def read_pins(path):
    """The ``name==version ; marker`` lines of a lock file (options, comments and ``-e .`` skipped)."""
    pins = []
    for line in pathlib.Path(path).read_text(encoding="utf-8").splitlines():
        line = line.split(" #", 1)[0].strip()
        if not line or line.startswith(("#", "-")):
            continue
        req = Requirement(line)
        spec = list(req.specifier)
        if len(spec) != 1 or spec[0].operator != "==":
            raise ValueError(f"{path}: {line!r} is not an exact pin (name==version)")
        pins.append(req)
    return pins


def marker_env(platform, python):
    major_minor = ".".join(python.split(".")[:2])
    env = {"implementation_name": "cpython", "platform_python_implementation": "CPython",
           "python_version": major_minor, "python_full_version": python, "implementation_version": python,
           "platform_release": "", "platform_version": ""}
    env.update(PLATFORMS[platform]["env"])
    return env


def applicable(pins, platform, python):
    env = marker_env(platform, python)
    return [r for r in pins if r.marker is None or Marker(str(r.marker)).evaluate(env)]


def pip_download(pins, platform, python, dest):
    """Run pip download for ``pins``; returns (ok, stderr tail)."""
    abi = "cp" + "".join(python.split(".")[:2])
    cmd = [sys.executable, "-m", "pip", "download", "--quiet", "--no-deps", "--only-binary=:all:",
           "--python-version", python, "--implementation", "cp", "--abi", abi, "-d", str(dest)]
    for tag in PLATFORMS[platform]["tags"]:
        cmd += ["--platform", tag]
    cmd += [f"{r.name}=={next(iter(r.specifier)).version}" for r in pins]
    proc = subprocess.run(cmd, capture_output=True, text=True)
    return proc.returncode == 0, proc.stderr.strip().splitlines()[-1:] if proc.stderr.strip() else []


def check_target(pins, platform, python):
    """List of (pin, reason) that have no wheel for this target."""
    wanted = applicable(pins, platform, python)
    with tempfile.TemporaryDirectory() as tmp:
        ok, _ = pip_download(wanted, platform, python, tmp)
        if ok:
            got = {_norm(p.name.split("-")[0]) for p in pathlib.Path(tmp).glob("*.whl")}
            missing = [r for r in wanted if _norm(r.name) not in got]
            return len(wanted), [(r, "downloaded, but no wheel file found") for r in missing]
    failures = []  # one failed pin stops pip: find every failing pin one by one
    for r in wanted:
        with tempfile.TemporaryDirectory() as tmp:
            ok, tail = pip_download([r], platform, python, tmp)
            if not ok:
                failures.append((r, " ".join(tail)[:160]))
    return len(wanted), failures


def _norm(name):
    return re.sub(r"[-_.]+", "-", name).lower()


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("lock", nargs="?", default=str(ROOT / "environment.txt"))
    parser.add_argument("--target", choices=sorted(PLATFORMS), action="append", help="platform(s) to check")
    parser.add_argument("--python", choices=PYTHONS, action="append", help="Python version(s) to check")
    args = parser.parse_args(argv)
    pins = read_pins(args.lock)
    print(f"{args.lock}: {len(pins)} pins")
    bad = 0
    for platform in args.target or list(PLATFORMS):
        for python in args.python or PYTHONS:
            n, failures = check_target(pins, platform, python)
            status = "all wheels" if not failures else f"{len(failures)} without a wheel"
            print(f"{platform:15s} CPython {python:7s} {n:4d} pins applicable: {status}", flush=True)
            for r, why in failures:
                print(f"    {r}: {why}")
            bad += bool(failures)
    print("every pin installs from wheels on every target" if not bad else f"{bad} target(s) fail")
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main())
