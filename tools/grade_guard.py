"""Guard rails for grading a submission: the grading process may change files only inside its own work folder.

    python tools/grade_guard.py WORK_DIR tools/grade.py [ARGS ...]

installs a Python audit hook (PEP 578) and then runs ``tools/grade.py`` as ``__main__``. From then on, in that
process, writing, creating, renaming or deleting a file outside ``WORK_DIR`` (the submission's copy of the
grading tree with its home and temporary folders) raises ``PermissionError``, and starting another program
(``subprocess``, ``os.system``, ``os.exec*``, ``os.spawn*``, ``os.fork``) or signalling another process raises too;
reading is allowed. So a submission that deletes or overwrites files elsewhere (the instructor's home, the other
submissions, the shared grading tree) fails its checks instead, and the files stay.

This stops plain Python code, not a determined attacker: code that calls the C library through ``ctypes``, or
that works through a directory file descriptor, is not checked (numba needs ``ctypes``, so it cannot be barred).
The container Gradescope runs each submission in (tools/gradescope.py) is the sandbox for that.
"""
from __future__ import annotations

import os
import pathlib
import runpy
import sys

WRITE_FLAGS = os.O_WRONLY | os.O_RDWR | os.O_CREAT | os.O_TRUNC | os.O_APPEND
PATH_EVENTS = {           # event: (position of a path it changes, position of that path's dir_fd or None), ...
    "os.remove": ((0, 1),), "os.rmdir": ((0, 1),), "os.rename": ((0, 2), (1, 3)), "os.replace": ((0, 2), (1, 3)),
    "os.mkdir": ((0, 2),), "os.chmod": ((0, 2),), "os.chown": ((0, 3),), "os.utime": ((0, 3),),
    "os.symlink": ((1, 2),), "os.link": ((1, 3),), "os.truncate": ((0, None),), "os.chflags": ((0, None),),
    "os.setxattr": ((0, None),), "os.removexattr": ((0, None),), "shutil.rmtree": ((0, 1),),
    "shutil.move": ((0, None), (1, None)), "shutil.copyfile": ((1, None),), "shutil.copytree": ((1, None),),
}
PROGRAM_EVENTS = {"subprocess.Popen", "os.system", "os.exec", "os.spawn", "os.posix_spawn", "os.fork",
                  "os.forkpty", "os.kill", "os.killpg", "os.startfile", "pty.spawn"}


def _inside(path, allowed: tuple) -> bool:
    if isinstance(path, int):                       # a file descriptor the process already holds
        return True
    try:
        real = os.path.realpath(os.fsdecode(path))
    except (TypeError, ValueError):
        return False
    return real == os.path.realpath(os.devnull) or any(real == a or real.startswith(a + os.sep) for a in allowed)


def install(work_dir) -> None:
    """From now on, in this process: no change to a file outside ``work_dir``, no new program, no signal."""
    allowed = (os.path.realpath(work_dir),)

    def hook(event, args):
        if event in PROGRAM_EVENTS:
            raise PermissionError("grading: %s is not allowed while a submission is graded" % event)
        if event == "open":
            path, _mode, flags = args
            if flags is not None and flags & WRITE_FLAGS and path is not None and not _inside(path, allowed):
                raise PermissionError("grading: writing %s (outside the submission's folder) is not allowed" % path)
        elif event in PATH_EVENTS:
            for i, fd_at in PATH_EVENTS[event]:
                path = args[i] if i < len(args) else None
                dir_fd = args[fd_at] if fd_at is not None and fd_at < len(args) else None
                relative_to_fd = isinstance(dir_fd, int) and not os.path.isabs(os.fsdecode(path or "."))
                if path is not None and not relative_to_fd and not _inside(path, allowed):
                    raise PermissionError("grading: %s of %s (outside the submission's folder) is not allowed"
                                          % (event, path))

    sys.addaudithook(hook)


def main(argv=None) -> None:
    argv = list(sys.argv[1:] if argv is None else argv)
    work_dir, script = pathlib.Path(argv[0]).resolve(), argv[1]
    install(work_dir)
    sys.argv = [script] + argv[2:]
    runpy.run_path(script, run_name="__main__")


if __name__ == "__main__":
    main()
