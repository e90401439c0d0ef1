"""The package's layering (helpers/README.md): no import cycle, and the peers (gtsam, g2opy) and the benchmark
code are never imported by the core. Imports are read from the source with ``ast`` (also those inside
functions), so a cycle hidden in a function body is found too."""
import ast
import pathlib

import pytest

ROOT = pathlib.Path(__file__).resolve().parents[1] / "helpers"


def _module_name(path):
    parts = list(path.relative_to(ROOT.parent).with_suffix("").parts)
    if parts[-1] == "__init__":
        parts.pop()
    return ".".join(parts)


def _imports(path):
    """(modules of helpers imported by the file, top-level names of every other import)."""
    name = _module_name(path)
    package = name if path.name == "__init__.py" else name.rpartition(".")[0]
    inside, outside = set(), set()
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
        if isinstance(node, ast.Import):
            for alias in node.names:
                (inside if alias.name.split(".")[0] == "helpers" else outside).add(alias.name)
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = package.split(".")
                base = base[:len(base) - node.level + 1]
                target = ".".join(base + ([node.module] if node.module else []))
            else:
                target = node.module
            if target.split(".")[0] != "helpers":
                outside.add(target)
                continue
            inside.add(target)
            for alias in node.names:            # "from . import camera" imports a module
                inside.add(f"{target}.{alias.name}")
    return inside, {o.split(".")[0] for o in outside}


MODULES = {_module_name(p): p for p in sorted(ROOT.rglob("*.py"))}
GRAPH = {}
EXTERNAL = {}
for _name, _path in MODULES.items():
    _inside, EXTERNAL[_name] = _imports(_path)
    GRAPH[_name] = {m for m in _inside if m in MODULES and m != _name}


def test_the_import_graph_was_read():
    assert len(MODULES) > 50
    assert "helpers.graph.edge" in GRAPH["helpers.graph.edges2d"]
    assert "helpers.graph" in GRAPH["helpers.drivebot.slam_system"]


def test_no_import_cycle_between_modules():
    # a package __init__ importing its own submodules is not a cycle; any other loop is
    def edges(m):
        return {d for d in GRAPH[m] if not (MODULES[d].name == "__init__.py" and m.startswith(d + "."))}

    state, stack = {}, []

    def visit(m):
        state[m] = "open"
        stack.append(m)
        for d in sorted(edges(m)):
            if state.get(d) == "open":
                cycle = stack[stack.index(d):] + [d]
                pytest.fail("import cycle: " + " -> ".join(cycle))
            if d not in state:
                visit(d)
        stack.pop()
        state[m] = "done"

    for m in sorted(MODULES):
        if m not in state:
            visit(m)


@pytest.mark.parametrize("forbidden", ["gtsam", "g2o", "benchmarks", "peer_runs"])
def test_core_never_imports_peers_or_benchmarks(forbidden):
    users = sorted(m for m, ext in EXTERNAL.items() if forbidden in ext)
    assert users == [], f"{forbidden} imported by {users}"


BOTTOM = {"helpers.paths", "helpers.validation", "helpers.timing"}


def test_graph_depends_only_on_itself_and_the_bottom_layer():
    for m, deps in GRAPH.items():
        if m.startswith("helpers.graph"):
            assert all(d.startswith("helpers.graph") or d in BOTTOM for d in deps), (m, deps)


def test_bottom_layer_imports_only_the_bottom_layer():
    for m in BOTTOM:
        assert GRAPH[m] <= BOTTOM, (m, GRAPH[m])


def test_only_the_advanced_part_imports_the_advanced_part():
    users = sorted(m for m, deps in GRAPH.items() if not m.startswith("helpers.advanced")
                   and any(d.startswith("helpers.advanced") for d in deps))
    assert users == [], f"course modules importing helpers.advanced: {users}"


def test_the_course_path_never_reaches_the_advanced_part():
    """The course path (tools/course_path.py: what notebooks 00–21 and the exercises import, and everything that
    imports) holds no module of helpers.advanced."""
    import importlib.util
    spec = importlib.util.spec_from_file_location("course_path", ROOT.parent / "tools" / "course_path.py")
    course_path = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(course_path)
    roots = set().union(*(course_path.notebook_imports(p) for p in course_path.COURSE_NOTEBOOKS))
    course = course_path.closure(roots | course_path.exercise_modules())
    assert len(course) > 40 and "helpers.graph" in course
    assert sorted(m for m in course if m.startswith("helpers.advanced")) == []
