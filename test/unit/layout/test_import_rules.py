"""The layout's import rules, checked on the source tree (ast, every import counted).

Function-local imports count as much as module-level ones: an import circle
hidden inside a function is still a circle.

* no import circle between the modules of ``servo_axis``, nor between the
  packages of any one package (its subpackages and modules, each with all it
  holds: ``analysis`` -> ``friction_id`` -> ``analysis`` was one);
* no node module imports a role's node module (the composed container aside),
  and a role's parts (``nodes/<role>_*.py``) are imported by that role only;
* ``servo_axis.realtime`` imports nothing of the project but ``core``, and
  nothing but numpy and the standard library;
* ``servo_axis.core`` imports nothing of the project outside ``core``, and
  nothing but numpy, scipy, numba (only ``core.kernels``, which compiles the
  kernels) and the standard library;
* the kernel modules (``core/**/*_kernels.py``)
  import nothing of the project but ``core.kernels``, and no other module
  imports one at its top (numba is loaded only where a kernel is used);
* ``analysis`` and ``simulate`` import nothing of ``run`` (the resolver is ``params.resolve``);
* ``run`` imports none of the scenario's queries: it reads the plan (``params.run_plan``);
* nothing outside ``servo_axis.plugins`` imports a module of it: the suite
  finds its own extensions by entry point, as it finds an outside package's;
* ``simulate``, ``analysis``, ``identify``, ``params``, ``plugins``, ``realtime``,
  ``sweep``, ``wire.topics``, ``wire.layouts``, ``wire.checks``, ``wire.streams``,
  ``wire.cdr``, ``wire.sample_cdr``, ``wire.setpoint``, ``recording.reader`` and
  ``nodes.lockstep`` reach no rclpy and no ROS message package, directly or through
  other modules of the project.
"""

from __future__ import annotations

import ast
import sys
from pathlib import Path

import pytest

SRC = Path(__file__).resolve().parents[3] / "src"
PACKAGE = "servo_axis"
ROS = ("rclpy", "rosidl", "sensor_msgs", "std_msgs", "rosgraph_msgs", "builtin_interfaces",
       "rcl_interfaces", "ament_index_python")  # fmt: skip


def module_name(path: Path) -> str:
    parts = list(path.relative_to(SRC).with_suffix("").parts)
    if parts[-1] == "__init__":
        parts.pop()
    return ".".join(parts)


MODULES = {module_name(p): p for p in (SRC / PACKAGE).rglob("*.py")}


def imports_of(name: str) -> set[str]:
    """Every module ``name`` imports, anywhere in it (absolute names)."""
    path = MODULES[name]
    tree = ast.parse(path.read_text())
    package = name if path.name == "__init__.py" else name.rpartition(".")[0]
    found: set[str] = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            found.update(alias.name for alias in node.names)
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                anchor = package.split(".")
                anchor = anchor[: len(anchor) - node.level + 1]
                base = ".".join([*anchor, base] if base else anchor)
            found.add(base)
            # `from pkg import module` imports the module too.
            found.update(f"{base}.{a.name}" for a in node.names if f"{base}.{a.name}" in MODULES)
    return found


def project_imports(name: str) -> set[str]:
    """The project modules ``name`` imports (packages resolved to their __init__)."""
    return {m for m in imports_of(name) if m in MODULES and m != name}


GRAPH = {name: project_imports(name) for name in MODULES}


def test_the_source_tree_is_found() -> None:
    assert {"servo_axis.core.models.ball_screw", "servo_axis.nodes.plant"} <= set(MODULES)


def test_no_import_circle() -> None:
    # A package's __init__ is not an edge back into its own modules.
    def edges(name: str) -> set[str]:
        return {m for m in GRAPH[name] if not name.startswith(m + ".")}

    state: dict[str, int] = {}
    stack: list[str] = []

    def visit(name: str) -> None:
        state[name] = 1
        stack.append(name)
        for nxt in sorted(edges(name)):
            if state.get(nxt) == 1:
                cycle = [*stack[stack.index(nxt) :], nxt]
                pytest.fail("import circle: " + " -> ".join(cycle))
            if nxt not in state:
                visit(nxt)
        stack.pop()
        state[name] = 2

    for name in sorted(GRAPH):
        if name not in state:
            visit(name)


def is_package(name: str) -> bool:
    return MODULES[name].name == "__init__.py"


def unit_in(package: str, name: str) -> str | None:
    """What of ``package`` holds module ``name``: the subpackage or module right below it.

    None for a module outside ``package`` and for its own ``__init__``. A kernel
    module is a unit of its own: it imports nothing but the compiler (so it
    closes no circle), and numba makes a family's kernels share one module,
    which another package may call (``core.friction.maxwell_slip`` the
    screws' ``core.models.ball_screw_kernels``).
    """
    if not name.startswith(package + "."):
        return None
    if is_kernel_module(name):
        return name
    return package + "." + name[len(package) + 1 :].split(".")[0]


def package_circles(graph: dict[str, set[str]], package: str) -> list[list[str]]:
    """The circles between what ``package`` holds, each with the imports that make its edges.

    ``a -> b`` when a module of ``a`` (anywhere inside it) imports a module of
    ``b``; each circle is returned once, as its strongly connected set of units.
    """
    edges: dict[str, dict[str, tuple[str, str]]] = {}
    for name, imported in sorted(graph.items()):
        a = unit_in(package, name)
        if a is None:
            continue
        for other in sorted(imported):
            b = unit_in(package, other)
            if b is not None and b != a:
                edges.setdefault(a, {}).setdefault(b, (name, other))
    # Tarjan's strongly connected sets: a set of two or more units is a circle.
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    circles: list[list[str]] = []

    def visit(v: str) -> None:
        index[v] = low[v] = len(index)
        stack.append(v)
        for w in sorted(edges.get(v, {})):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            members = []
            while True:
                w = stack.pop()
                members.append(w)
                if w == v:
                    break
            if len(members) > 1:
                circles.append(sorted(members))

    for v in sorted(edges):
        if v not in index:
            visit(v)
    return [
        [f"{a} -> {b} ({edges[a][b][0]} imports {edges[a][b][1]})"
         for a in circle for b in circle if b in edges.get(a, {})]
        for circle in circles
    ]  # fmt: skip


PACKAGES = sorted(m for m in MODULES if is_package(m))


@pytest.mark.parametrize("package", PACKAGES)
def test_no_circle_between_packages(package: str) -> None:
    circles = package_circles(GRAPH, package)
    assert not circles, f"circles between the packages of {package}: " + "; ".join(
        ", ".join(c) for c in circles
    )


def test_the_package_check_sees_the_old_circle() -> None:
    """The circle through ``analysis.ballnut`` (issue 39), which no module circle showed."""
    graph = {
        "servo_axis.analysis.ballnut": {"servo_axis.friction_id", "servo_axis.simulate"},
        "servo_axis.friction_id": {"servo_axis.analysis.signals", "servo_axis.analysis.summary"},
        "servo_axis.analysis.summary": {"servo_axis.analysis.signals"},
        "servo_axis.analysis.signals": set(),
        "servo_axis.simulate": set(),
    }
    assert package_circles(graph, "servo_axis.analysis") == []
    (circle,) = package_circles(graph, "servo_axis")
    assert sorted(circle) == [
        "servo_axis.analysis -> servo_axis.friction_id "
        "(servo_axis.analysis.ballnut imports servo_axis.friction_id)",
        "servo_axis.friction_id -> servo_axis.analysis "
        "(servo_axis.friction_id imports servo_axis.analysis.signals)",
    ]
    # and a kernel module shared across packages closes no circle
    kernels = {
        "servo_axis.core.friction.maxwell_slip": {"servo_axis.core.models.ball_screw_kernels"},
        "servo_axis.core.models.ball_screw": {"servo_axis.core.friction.maxwell_slip"},
        "servo_axis.core.models.ball_screw_kernels": {"servo_axis.core.kernels"},
    }
    assert package_circles(kernels, "servo_axis.core") == []


#: The node of each role (``nodes/<role>.py``); a role's own parts are ``nodes/<role>_*.py``.
ROLES = ("plant", "feedback", "feedforward", "learning", "identifier", "recorder")


def test_no_node_module_imports_another() -> None:
    nodes = {m for m in MODULES if m.startswith("servo_axis.nodes.")}
    roles = {f"servo_axis.nodes.{r}" for r in ROLES}
    assert roles <= nodes
    for name in sorted(nodes - {"servo_axis.nodes.composed"}):
        assert not (GRAPH[name] & roles), f"{name} imports {sorted(GRAPH[name] & roles)}"


def is_kernel_module(name: str) -> bool:
    """A module of compiled kernels (or the compiler): ``core/**/kernels.py``, ``*_kernels.py``."""
    last = name.rpartition(".")[2]
    return name.startswith("servo_axis.core.") and (last == "kernels" or last.endswith("_kernels"))


KERNEL_MODULES = sorted(m for m in MODULES if is_kernel_module(m))
#: The one module that imports numba: it compiles every kernel (:func:`compiled`).
COMPILER = "servo_axis.core.kernels"


def test_the_kernel_modules_are_found() -> None:
    assert {
        COMPILER,
        "servo_axis.core.models.ball_screw_kernels",
        "servo_axis.core.models.tilting_table_kernels",
        "servo_axis.core.feedforward.ptc_kernels",
        "servo_axis.core.friction.gms_kernels",
        "servo_axis.core.identification.online.dlpid_kernels",
    } <= set(KERNEL_MODULES)


def test_a_roles_parts_are_imported_by_that_role_only() -> None:
    """``nodes/feedforward_estimates.py`` is the feedforward's, used by no other module;
    the shared parts of every node (``base``, ``inputs``, ...) belong to no role."""
    parts = {
        m: role for m in MODULES for role in ROLES if m.startswith(f"servo_axis.nodes.{role}_")
    }
    assert "servo_axis.nodes.feedforward_estimates" in parts
    for name in sorted(MODULES):
        for part in sorted(GRAPH[name] & set(parts)):
            owner = f"servo_axis.nodes.{parts[part]}"
            assert name in (owner, part) or name.startswith(f"{owner}_"), (
                f"{name} imports {part}, a part of {owner}"
            )


def test_core_imports_only_core_numpy_scipy_numba_and_the_standard_library() -> None:
    allowed_third_party = {"numpy", "scipy"}
    for name in sorted(m for m in MODULES if m.startswith("servo_axis.core")):
        for imported in imports_of(name):
            top = imported.split(".")[0]
            if top == "numba":
                assert name == COMPILER, f"{name} imports numba (compile with core.kernels)"
                continue
            if top == PACKAGE:
                assert imported.startswith("servo_axis.core"), f"{name} imports {imported}"
            else:
                assert top in allowed_third_party or top in sys.stdlib_module_names, (
                    f"{name} imports {imported}"
                )


def test_realtime_imports_only_core_numpy_and_the_standard_library() -> None:
    # Realtime mode's parts are importable wherever the core is: the nodes, the
    # runner and the wire's stream gates use them, and they use none of those.
    names = sorted(m for m in MODULES if m.startswith("servo_axis.realtime"))
    assert "servo_axis.realtime.deadlines" in names
    for name in names:
        for imported in imports_of(name):
            top = imported.split(".")[0]
            if top == PACKAGE:
                assert imported.startswith(("servo_axis.core", "servo_axis.realtime")), (
                    f"{name} imports {imported}"
                )
            else:
                assert top == "numpy" or top in sys.stdlib_module_names, (
                    f"{name} imports {imported}"
                )


def test_a_kernel_module_imports_only_the_compiler() -> None:
    # numba checks a cached kernel against its own file only: a kernel that
    # called a kernel of another file would keep that kernel's old code after
    # an edit. So a family's kernels are in one module, which imports no other.
    for name in KERNEL_MODULES:
        project = GRAPH[name] - {COMPILER}
        assert not project, f"{name} imports {sorted(project)}"


def test_the_kernels_are_imported_where_they_are_used() -> None:
    # numba costs about half a second to import: no module imports a kernel
    # module at its top (a kernel module the compiler aside), so that only a
    # process that builds a plant, an adaptive PTC, a GMS term or an
    # identifier (or moves a Maxwell-slip set) pays for it.
    for name, path in sorted(MODULES.items()):
        for node in ast.parse(path.read_text()).body:
            if isinstance(node, ast.ImportFrom) and node.module:
                names = {node.module, *(f"{node.module}.{a.name}" for a in node.names)}
            elif isinstance(node, ast.Import):
                names = {a.name for a in node.names}
            else:
                continue
            for kernels in set(KERNEL_MODULES) & names:
                allowed = is_kernel_module(name) and kernels == COMPILER
                assert allowed, f"{name} imports {kernels} at its top"


def reach(name: str) -> set[str]:
    """Every module ``name`` imports, directly or through project modules."""
    seen: set[str] = set()
    todo = [name]
    out: set[str] = set()
    while todo:
        current = todo.pop()
        if current in seen:
            continue
        seen.add(current)
        for imported in imports_of(current):
            out.add(imported)
            if imported in MODULES:
                todo.append(imported)
            # Importing a.b.c runs a/__init__ and a/b/__init__ too.
            parts = imported.split(".")
            todo += [
                ".".join(parts[:i]) for i in range(1, len(parts)) if ".".join(parts[:i]) in MODULES
            ]
    return out


ROS_FREE = [
    "servo_axis.simulate",
    "servo_axis.storage",
    "servo_axis.wire.topics",
    "servo_axis.wire.layouts",
    "servo_axis.wire.checks",
    "servo_axis.wire.streams",
    "servo_axis.wire.cdr",
    "servo_axis.wire.sample_cdr",
    "servo_axis.wire.setpoint",
    "servo_axis.wire.joint_states",
    "servo_axis.recording.reader",
    "servo_axis.nodes.lockstep",
    *sorted(
        m
        for m in MODULES
        if m.startswith(
            (
                "servo_axis.analysis",
                "servo_axis.identify",
                "servo_axis.params",
                "servo_axis.plugins",
                "servo_axis.realtime",
                "servo_axis.sweep",
            )
        )
    ),
]


def test_the_extensions_are_found_by_entry_point_only() -> None:
    plugins = {m for m in MODULES if m.startswith("servo_axis.plugins")}
    assert "servo_axis.plugins.ball_screw" in plugins
    for name in sorted(set(MODULES) - plugins):
        assert not (GRAPH[name] & plugins), f"{name} imports {sorted(GRAPH[name] & plugins)}"


def test_simulate_and_analysis_resolve_a_scenario_without_the_runner() -> None:
    # One resolver (params.resolve) turns a scenario into each node's values.
    for name in sorted(
        m for m in MODULES if m.startswith(("servo_axis.analysis", "servo_axis.simulate"))
    ):
        runner = sorted(m for m in GRAPH[name] if m.startswith("servo_axis.run"))
        assert not runner, f"{name} imports {runner}"


#: What asks a scenario (a raw mapping) a question: the plan asks them once, the runner not at all.
SCENARIO_QUERIES = {
    "node_params",
    "node_values",
    "shared",
    "axis_view",
    "axes_of",
    "roles_of",
    "copied",
    "checked_values",
    "handshake_overrides",
    "role_topics",
    "presence_topic",
    "recorder_topics",
}


def test_the_runner_reads_the_plan_not_the_scenario() -> None:
    runner = sorted(m for m in MODULES if m.startswith("servo_axis.run"))
    assert "servo_axis.run.prepare" in runner
    for name in runner:
        for node in ast.walk(ast.parse(MODULES[name].read_text())):
            if isinstance(node, ast.ImportFrom) and (node.module or "").startswith("servo_axis."):
                asked = sorted({a.name for a in node.names} & SCENARIO_QUERIES)
                assert not asked, f"{name} imports {asked} from {node.module}"


@pytest.mark.parametrize("name", ROS_FREE)
def test_headless_modules_reach_no_ros(name: str) -> None:
    ros = sorted(m for m in reach(name) if m.split(".")[0] in ROS)
    assert not ros, f"{name} reaches {ros}"


def test_the_checker_sees_a_function_local_import(tmp_path: Path) -> None:
    """The rules would catch an import hidden in a function (the old circle's disguise)."""
    src = "def f():\n    from servo_axis.nodes import plant\n    import rclpy\n"
    tree = ast.parse(src)
    names = {
        n.module if isinstance(n, ast.ImportFrom) else n.names[0].name
        for n in ast.walk(tree)
        if isinstance(n, ast.Import | ast.ImportFrom)
    }
    assert names == {"servo_axis.nodes", "rclpy"}
