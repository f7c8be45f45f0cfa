"""The layout's import rules, checked on the source tree (ast, every import counted).

Function-local imports count as much as module-level ones: an import circle
hidden inside a function is still a circle.

* no import circle between the modules of ``servo_axis``;
* no node module imports another node module (the composed container aside);
* ``servo_axis.core`` imports nothing of the project outside ``core``, and
  nothing but numpy, scipy, numba (only ``core.kernels``, the compiled
  sub-step loops, and ``core.identification.kernels``, the identifier's
  filters and RLS) and the standard library;
* ``analysis`` and ``simulate`` import nothing of ``run`` (the resolver is ``params.resolve``);
* ``run`` imports none of the scenario's queries: it reads the plan (``params.run_plan``);
* nothing outside ``servo_axis.plugins`` imports a module of it: the suite
  finds its own extensions by entry point, as it finds an outside package's;
* ``simulate``, ``analysis``, ``friction_id``, ``gms_fit``, ``params``, ``plugins``,
  ``study``, ``wire.topics``, ``wire.layouts``, ``wire.checks``, ``wire.streams``,
  ``wire.cdr``, ``wire.sample_cdr`` and ``recording.reader`` reach no rclpy and no ROS message
  package, directly or through other modules of the project.
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


def test_no_node_module_imports_another() -> None:
    nodes = {m for m in MODULES if m.startswith("servo_axis.nodes.")}
    shared = {
        "servo_axis.nodes.base",
        "servo_axis.nodes.runtime",
        "servo_axis.nodes.lockstep",
        "servo_axis.nodes.parameters",
        "servo_axis.nodes.diagnostics",
    }
    roles = nodes - shared - {"servo_axis.nodes.composed"}
    for name in sorted(nodes - {"servo_axis.nodes.composed"}):
        assert not (GRAPH[name] & roles), f"{name} imports {sorted(GRAPH[name] & roles)}"


#: The compiled modules (numba): the plants' sub-step loops, the identifier's filters and RLS.
KERNEL_MODULES = ("servo_axis.core.kernels", "servo_axis.core.identification.kernels")


def test_core_imports_only_core_numpy_scipy_numba_and_the_standard_library() -> None:
    allowed_third_party = {"numpy", "scipy"}
    for name in sorted(m for m in MODULES if m.startswith("servo_axis.core")):
        for imported in imports_of(name):
            top = imported.split(".")[0]
            if top == "numba":
                assert name in KERNEL_MODULES, f"{name} imports numba"
                continue
            if top == PACKAGE:
                assert imported.startswith("servo_axis.core"), f"{name} imports {imported}"
            else:
                assert top in allowed_third_party or top in sys.stdlib_module_names, (
                    f"{name} imports {imported}"
                )


def test_the_kernels_are_imported_where_a_plant_is_built() -> None:
    # numba costs about half a second to import: no module imports the kernels
    # at its top, so that only a process that builds a plant (or moves a
    # Maxwell-slip set) pays for it.
    for name, path in sorted(MODULES.items()):
        for node in ast.parse(path.read_text()).body:
            if isinstance(node, ast.ImportFrom) and node.module:
                names = {node.module, *(f"{node.module}.{a.name}" for a in node.names)}
            elif isinstance(node, ast.Import):
                names = {a.name for a in node.names}
            else:
                continue
            for kernels in KERNEL_MODULES:
                assert kernels not in names, f"{name} imports {kernels} at its top"


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
    "servo_axis.friction_id",
    "servo_axis.gms_fit",
    "servo_axis.storage",
    "servo_axis.wire.topics",
    "servo_axis.wire.layouts",
    "servo_axis.wire.checks",
    "servo_axis.wire.streams",
    "servo_axis.wire.cdr",
    "servo_axis.wire.sample_cdr",
    "servo_axis.recording.reader",
    *sorted(
        m
        for m in MODULES
        if m.startswith(
            ("servo_axis.analysis", "servo_axis.params", "servo_axis.plugins", "servo_axis.sweep")
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
