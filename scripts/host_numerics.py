#!/usr/bin/env python3
"""Where a scenario's numbers depend on the host: each source, its first sample and function.

Runs a scenario's core-only loop (the plain-call loop of
:mod:`servo_axis.simulate` that reproduces its node graph) in child
processes, once in the portable numeric environment of
:mod:`servo_axis.numerics` and once per *source* with that source left to
the host and set the way another CPU would set it:

=============  ==========================================================
source         the variant that stands in for another machine
=============  ==========================================================
``numpy``      numpy's dispatched SIMD paths on (X86_V3, X86_V4, AVX-512)
               against the baseline the portable environment pins
``libm``       glibc's FMA/AVX2 variants of ``sin``, ``exp``, ... against
               its SSE2 ones (``GLIBC_TUNABLES`` hwcaps)
``openblas``   OpenBLAS's kernels for this CPU, and for Haswell, against
               the pinned Nehalem ones (``OPENBLAS_CORETYPE``)
``numba``      numba compiling for this CPU against the generic x86-64
               target (``NUMBA_CPU_NAME``)
=============  ==========================================================

For each it prints the first control step at which each recorded signal
differs, and the first traced function whose result differs for the same
arguments: every function of ``math``, numpy's transcendental ufuncs,
``np.dot``/``np.matmul``/``np.linalg``, ``scipy.linalg`` and
``scipy.signal`` and every compiled (numba) kernel the loop calls from
Python. A difference that first shows in a traced call's *arguments* came
from an operation between two traced calls (``a @ b`` is not traced); the
line says so and names the caller.

    .venv/bin/python scripts/host_numerics.py pid_disturbance ptc_nominal
    .venv/bin/python scripts/host_numerics.py --all --json hosts.json
"""

from __future__ import annotations

import argparse
import json
import math
import os
import subprocess
import sys
import tempfile
import types
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]


#: The variants of each source: ``{source: {variant: environment}}`` set on
#: top of the portable environment with ``SERVO_AXIS_NUMERICS=native`` for
#: the source's own variables (so that they reach the process unchanged).
SOURCES: dict[str, dict[str, dict[str, str]]] = {
    "numpy": {
        "host": {"NPY_DISABLE_CPU_FEATURES": ""},
        "no AVX-512": {"NPY_DISABLE_CPU_FEATURES": "X86_V4 AVX512_ICL AVX512_SPR"},
    },
    "libm": {"host": {"GLIBC_TUNABLES": ""}},
    "openblas": {
        "host": {"OPENBLAS_CORETYPE": ""},
        "Haswell": {"OPENBLAS_CORETYPE": "Haswell"},
        "Sandybridge": {"OPENBLAS_CORETYPE": "Sandybridge"},
    },
    "numba": {"host": {"NUMBA_CPU_NAME": "", "NUMBA_CPU_FEATURES": ""}},
}


def child_environment(variant: dict[str, str]) -> dict[str, str]:
    """The portable environment with ``variant``'s variables replaced (``""``: unset)."""
    from servo_axis import numerics

    env = numerics.portable_environment(os.environ)
    env["SERVO_AXIS_NUMERICS"] = "native"
    for key, value in variant.items():
        if value:
            env[key] = value
        else:
            env.pop(key, None)
    return env


# --- the child: trace, then run the loop ------------------------------------

_CALLS: list[tuple[str, str, int, str, str]] = []
_STEP = [0]


def _digest(value: object) -> str:
    import hashlib

    import numpy as np

    h = hashlib.sha1()

    def feed(v: object) -> None:
        if isinstance(v, np.ndarray):
            h.update(str(v.dtype).encode())
            h.update(np.ascontiguousarray(v).tobytes())
        elif isinstance(v, (float, int, bool, np.generic)):
            h.update(np.asarray(v).tobytes())
        elif isinstance(v, (tuple, list)):
            h.update(b"(")
            for x in v:
                feed(x)
            h.update(b")")
        elif isinstance(v, dict):
            for k in sorted(v, key=str):
                h.update(str(k).encode())
                feed(v[k])
        elif v is None or isinstance(v, str):
            h.update(repr(v).encode())
        else:
            h.update(type(v).__name__.encode())

    feed(value)
    return h.hexdigest()[:16]


def _caller() -> str:
    frame = sys._getframe(2)
    while frame is not None:
        name = frame.f_code.co_filename
        if "servo_axis" in name and "host_numerics" not in name:
            rel = name.split("src/")[-1]
            return f"{rel}:{frame.f_lineno}"
        frame = frame.f_back
    return "?"


def _wrap(name: str, fn: object) -> object:
    def traced(*args: object, **kwargs: object) -> object:
        out = fn(*args, **kwargs)  # type: ignore[operator]
        _CALLS.append((name, _caller(), _STEP[0], _digest((args, kwargs)), _digest(out)))
        return out

    traced.__wrapped__ = fn  # type: ignore[attr-defined]
    return traced


_TRACED_NUMPY = (
    "exp sin cos tan arctan arctan2 arcsin arccos tanh sinh cosh log log10 log2 log1p "
    "expm1 power hypot sqrt cbrt exp2 dot matmul inner outer einsum convolve"
).split()
_TRACED_LINALG = "solve inv eig eigvals eigh eigvalsh svd lstsq pinv det norm qr cholesky".split()


class _Traced(types.ModuleType):
    """A module's stand-in whose functions of interest are traced (the rest passes through)."""

    def __init__(self, module: types.ModuleType, prefix: str, names: set[str] | None) -> None:
        super().__init__(module.__name__)
        self._module, self._prefix, self._names = module, prefix, names

    def __getattr__(self, attr: str) -> object:
        value = getattr(self._module, attr)
        if isinstance(value, types.ModuleType):
            inner = _stand_in(value)
            return inner if inner is not None else value
        if callable(value) and not isinstance(value, type) and not attr.startswith("_"):
            if self._names is None or attr in self._names:
                return _wrap(f"{self._prefix}.{attr}", value)
        return value


def _stand_in(module: types.ModuleType) -> types.ModuleType | None:
    import numpy as np

    if module is math:
        return _Traced(math, "math", None)

    if module is np:
        return _Traced(np, "np", set(_TRACED_NUMPY))
    if module is np.linalg:
        return _Traced(np.linalg, "np.linalg", set(_TRACED_LINALG))
    return None


def _install_tracing() -> None:
    """Trace the calls that may depend on the CPU, where servo_axis's Python code makes them.

    Each module of the package but the compiled kernels' gets stand-ins for
    ``math``, ``numpy`` and ``numpy.linalg``, and traced copies of the
    functions it imported from them and of the kernels it calls (the kernel
    modules keep the real ones: numba compiles against them); the functions
    of ``scipy.linalg`` and ``scipy.signal`` are traced in their modules.
    """
    import numpy as np
    import scipy.linalg
    import scipy.signal
    from numba.core.registry import CPUDispatcher

    # scipy's own functions are traced in their modules (a local `import
    # scipy.linalg` sees them); numba compiles nothing of scipy's.
    for mod, prefix in ((scipy.linalg, "scipy.linalg"), (scipy.signal, "scipy.signal")):
        for attr in getattr(mod, "__all__", []):
            fn = getattr(mod, attr, None)
            if callable(fn) and not isinstance(fn, type):
                setattr(mod, attr, _wrap(f"{prefix}.{attr}", fn))
    origins = {"math": "math", "numpy": "np"}
    for name, mod in list(sys.modules.items()):
        if mod is None or not name.startswith("servo_axis") or name.endswith("kernels"):
            continue
        if name.startswith("servo_axis.numerics"):
            continue
        for attr, value in list(vars(mod).items()):
            if isinstance(value, types.ModuleType):
                stand_in = _stand_in(value)
                if stand_in is not None:
                    setattr(mod, attr, stand_in)
            elif isinstance(value, CPUDispatcher):
                setattr(mod, attr, _wrap(f"numba {value.py_func.__module__}.{attr}", value))
            elif callable(value) and not isinstance(value, type):
                home = getattr(value, "__module__", None) or ""
                for root, prefix in origins.items():
                    if (
                        home == root
                        or home.startswith(root + ".")
                        or (root == "numpy" and isinstance(value, np.ufunc))
                    ):
                        if root == "numpy" and attr not in _TRACED_NUMPY:
                            break
                        setattr(mod, attr, _wrap(f"{prefix}.{attr}", value))
                        break


def _child(scenario: str, out: str) -> None:
    import numpy as np

    from servo_axis.core.feedback.loop import FeedbackLoop
    from servo_axis.params import factories  # noqa: F401  (imports the kernels' modules)

    current = FeedbackLoop.current

    def counted(self: FeedbackLoop, **kwargs: float) -> float:
        _STEP[0] += 1
        return current(self, **kwargs)

    FeedbackLoop.current = counted  # type: ignore[method-assign]
    path = Path(scenario)
    from servo_axis.params.scenario import load_scenario
    from servo_axis.simulate import simulate, simulate_identification, simulate_learning

    sc = load_scenario(path)
    fn = (
        simulate_identification
        if "identifier" in sc
        else simulate_learning
        if "learning" in sc
        else simulate
    )
    # The plugins are imported (and the kernels compiled) on the first build:
    # trace after it.
    fn(path, steps=2)
    _install_tracing()
    _CALLS.clear()
    _STEP[0] = 0
    result = fn(path)
    traj = getattr(result, "trajectory", result)
    arrays = {k: getattr(traj, k) for k in traj.__dataclass_fields__}
    if hasattr(result, "estimates"):
        arrays["estimates"] = np.asarray(result.estimates, float)
    if hasattr(result, "error_m"):
        arrays["learned_error_m"] = np.asarray(result.error_m, float)
    np.savez(out + ".npz", **arrays)
    Path(out + ".calls.json").write_text(json.dumps(_CALLS))


# --- the parent: compare -----------------------------------------------------


def run_child(scenario: Path, env: dict[str, str], work: Path, tag: str) -> Path:
    out = work / tag
    proc = subprocess.run(
        [sys.executable, __file__, "--child", str(scenario), str(out)],
        env=env,
        capture_output=True,
        text=True,
        check=False,
    )
    if proc.returncode:
        raise SystemExit(f"{scenario.stem} [{tag}]: the child failed:\n{proc.stderr[-3000:]}")
    return out


def first_differences(base: Path, other: Path) -> dict[str, int | None]:
    """The first row at which each saved signal differs (``None``: identical)."""
    import numpy as np

    a, b = np.load(f"{base}.npz"), np.load(f"{other}.npz")
    out: dict[str, int | None] = {}
    for key in a.files:
        x, y = a[key], b[key]
        if x.shape != y.shape:
            out[key] = 0
            continue
        rows = np.nonzero(~((x == y) | (np.isnan(x) & np.isnan(y))).reshape(x.shape[0], -1).all(1))
        out[key] = int(rows[0][0]) if rows[0].size else None
    return out


def first_function(base: Path, other: Path) -> str | None:
    """The first traced call whose result parts, or whose arguments already did."""
    a = json.loads(Path(f"{base}.calls.json").read_text())
    b = json.loads(Path(f"{other}.calls.json").read_text())
    for i, (x, y) in enumerate(zip(a, b, strict=False)):
        if x == y:
            continue
        name, where, step = x[0], x[1], x[2]
        if x[0] != y[0]:
            return f"call {i}: the calls part ({x[0]} at {x[1]} vs {y[0]} at {y[1]}), step {step}"
        if x[3] != y[3]:
            return (
                f"before {name} at {where} (step {step}): its arguments already differ, "
                "from an untraced operation since the previous traced call"
                + (f" ({a[i - 1][0]} at {a[i - 1][1]})" if i else "")
            )
        return f"{name} at {where}, step {step}: the same arguments, another result"
    if len(a) != len(b):
        return f"the traced calls end at {min(len(a), len(b))} vs {max(len(a), len(b))}"
    return None


def main() -> int:
    if len(sys.argv) > 1 and sys.argv[1] == "--child":
        _child(sys.argv[2], sys.argv[3])
        return 0
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("scenarios", nargs="*", help="shipped scenario names")
    parser.add_argument("--all", action="store_true", help="every shipped single-axis scenario")
    parser.add_argument("--source", action="append", choices=sorted(SOURCES), help="only these")
    parser.add_argument("--json", type=Path, help="write the table as JSON too")
    args = parser.parse_args()
    from servo_axis.params.scenario import axes_of, load_scenario, scenario_dir, scenario_names

    names = list(args.scenarios) or []
    if args.all:
        names = [
            n for n in scenario_names() if not axes_of(load_scenario(scenario_dir() / f"{n}.yaml"))
        ]
    if not names:
        parser.error("give scenario names or --all")
    sources = args.source or sorted(SOURCES)
    table = []
    with tempfile.TemporaryDirectory(prefix="host_numerics_") as tmp:
        work = Path(tmp)
        for name in names:
            path = scenario_dir() / f"{name}.yaml"
            base = run_child(path, child_environment({}), work, f"{name}-portable")
            for source in sources:
                for variant, setting in SOURCES[source].items():
                    tag = f"{name}-{source}-{variant}".replace(" ", "_")
                    other = run_child(path, child_environment(setting), work, tag)
                    diffs = first_differences(base, other)
                    parted = [v for v in diffs.values() if v is not None]
                    row = {
                        "scenario": name,
                        "source": source,
                        "variant": variant,
                        "first_step": min(parted) if parted else None,
                        "signals": diffs,
                        "function": first_function(base, other) if parted else None,
                    }
                    table.append(row)
                    first = "identical" if not parted else f"first step {min(parted)}"
                    print(f"{name:32s} {source:8s} {variant:12s} {first}", flush=True)
                    if parted:
                        sig = ", ".join(f"{k} {v}" for k, v in diffs.items() if v is not None)
                        print(f"    signals: {sig}\n    function: {row['function']}", flush=True)
    if args.json:
        args.json.write_text(json.dumps(table, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
