"""The numeric environment of a run: the same numbers on every x86-64 host.

numpy, glibc's libm, OpenBLAS and numba each pick their code by the CPU
they run on, and their results differ in the last bits from one pick to
another (measured: ``docs/explanation/numerics.md``):

* numpy dispatches its ufuncs to SIMD paths (X86_V3, X86_V4, AVX-512)
  beyond its X86_V2 baseline: ``np.exp`` is not the same function on an
  AVX-512 host;
* glibc's libm (``sin``, ``cos``, ``exp``, ``log``, ``pow``, ``atan2``,
  ``tanh``, ...) takes its FMA variants where the CPU has FMA and AVX2, which
  round differently from its SSE2 ones; Python's ``math`` and numpy's
  baseline paths call it;
* OpenBLAS (numpy's and scipy's) chooses its kernels by the CPU model
  (SkylakeX, Haswell, Zen, ...): every ``@`` of two matrices, every solve,
  every ``expm`` sums in the kernel's order, with or without FMA;
* numba compiles for the host CPU.

:func:`portable_environment` pins each of them to a choice every x86-64
host that runs numpy can make: numpy's baseline (no dispatched path),
libm's SSE2 variants, OpenBLAS's Nehalem kernels on one thread, numba's
generic target. These are read when a process starts (glibc's tunables by
the dynamic loader, the others when each library loads), so the
environment is given to a process, not changed inside one:
``python -m servo_axis`` (and every ``python -m servo_axis.<module>``)
starts again in it before anything else is imported (:func:`enter`), and
every process it starts inherits it. A script of one's own that wants the
same numbers runs under ``python -m servo_axis.numerics SCRIPT [ARGS]``.

``SERVO_AXIS_NUMERICS=native`` keeps the host's fastest paths (and its
numbers). Outside x86-64 Linux nothing is pinned: another architecture or
another C library computes other numbers (uncovered, and said so by
:func:`describe`).

This module imports nothing but the standard library: it runs before numpy.
"""

from __future__ import annotations

import os
import platform
import sys
from collections.abc import Mapping, Sequence

#: The variable that turns the pin off (``native``) or on (unset, ``portable``).
SWITCH = "SERVO_AXIS_NUMERICS"

#: numpy 2.4's dispatched targets beyond its X86_V2 baseline (``numpy._core.
#: _multiarray_umath.__cpu_dispatch__``; test/unit/test_portable_numerics.py checks
#: the list against the installed numpy).
NUMPY_DISPATCH = ("X86_V3", "X86_V4", "AVX512_ICL", "AVX512_SPR")

#: The CPU features glibc's libm variants are chosen by (its ifunc selectors:
#: FMA with AVX2, FMA4, AVX); masked, every function takes its SSE2 variant.
GLIBC_MASKED = ("AVX", "AVX2", "FMA", "FMA4")

#: The variables that pin the numeric paths, but for ``GLIBC_TUNABLES``,
#: which :func:`portable_environment` merges with what is already set.
PINNED: Mapping[str, str] = {
    "NPY_DISABLE_CPU_FEATURES": " ".join(NUMPY_DISPATCH),
    # An SSE3 kernel set that every x86-64-v2 CPU runs; one thread, so that
    # no reduction is split by the number of cores.
    "OPENBLAS_CORETYPE": "Nehalem",
    "OPENBLAS_NUM_THREADS": "1",
    "NUMBA_CPU_NAME": "generic",
    "NUMBA_CPU_FEATURES": "",
}

_HWCAPS = "glibc.cpu.hwcaps"

#: Settings that make this machine stand in for another one: each is what a
#: CPU without a feature, or of another model, would choose by itself (the
#: names of ``scripts/scenario_hashes.py --mask`` and of the suite's checks).
MASKS: Mapping[str, Mapping[str, str]] = {
    # numpy without its AVX-512 paths: an AVX2 host.
    "numpy": {"NPY_DISABLE_CPU_FEATURES": "X86_V4 AVX512_ICL AVX512_SPR"},
    # libm without FMA and AVX2: a host before Haswell (or a VM hiding them).
    "libm": {"GLIBC_TUNABLES": "glibc.cpu.hwcaps=-AVX2,-FMA"},
    # OpenBLAS's kernels for Haswell, as on an AVX2 host or a Zen.
    "openblas": {"OPENBLAS_CORETYPE": "Haswell"},
    # numba compiling for Haswell.
    "numba": {"NUMBA_CPU_NAME": "haswell"},
}


def supported(machine: str | None = None, system: str | None = None) -> bool:
    """Whether the pin applies here: x86-64 Linux (glibc)."""
    machine = platform.machine() if machine is None else machine
    system = platform.system() if system is None else system
    return machine in ("x86_64", "AMD64") and system == "Linux"


def _tunables(value: str) -> str:
    """``value`` (a ``GLIBC_TUNABLES`` string) with libm's variant features masked."""
    items = [item for item in value.split(":") if item]
    masks = [f"-{feature}" for feature in GLIBC_MASKED]
    for i, item in enumerate(items):
        name, _, caps = item.partition("=")
        if name == _HWCAPS:
            have = [c for c in caps.split(",") if c]
            items[i] = f"{_HWCAPS}=" + ",".join(have + [m for m in masks if m not in have])
            return ":".join(items)
    return ":".join([*items, f"{_HWCAPS}=" + ",".join(masks)])


def portable_environment(environ: Mapping[str, str]) -> dict[str, str]:
    """``environ`` with the numeric paths pinned (a copy; ``environ`` is unchanged).

    Parameters
    ----------
    environ : mapping of str to str
        An environment, e.g. ``os.environ``.

    Returns
    -------
    dict of str to str
        ``environ`` with :data:`PINNED` set (whatever it held: a value set
        by hand is overridden, as a CPU's own choice is) and libm's variant
        features masked in ``GLIBC_TUNABLES`` (other tunables kept). Unchanged
        but copied where :func:`supported` is false or ``SERVO_AXIS_NUMERICS``
        is ``native``.
    """
    if not supported() or environ.get(SWITCH, "portable") == "native":
        return dict(environ)
    return _pinned(environ)


def _pinned(environ: Mapping[str, str]) -> dict[str, str]:
    env = dict(environ)
    env.update(PINNED)
    env["GLIBC_TUNABLES"] = _tunables(env.get("GLIBC_TUNABLES", ""))
    return env


def is_portable(environ: Mapping[str, str]) -> bool:
    """Whether a process started with ``environ`` computes the portable numbers."""
    if not supported():
        return False
    pinned = _pinned(environ)
    return all(environ.get(k) == pinned[k] for k in (*PINNED, "GLIBC_TUNABLES"))


def mode(environ: Mapping[str, str] = os.environ) -> str:
    """``portable``, ``native`` (asked for) or ``host`` (not pinned, not asked)."""
    if is_portable(environ):
        return "portable"
    if environ.get(SWITCH) == "native":
        return "native"
    return "host"


def describe(environ: Mapping[str, str] = os.environ) -> str:
    """One line for a run's header: which numeric paths its processes take."""
    what = mode(environ)
    if what == "portable":
        return (
            "numerics: portable (numpy X86_V2 baseline, libm SSE2, OpenBLAS Nehalem on 1 "
            "thread, numba generic; the same numbers on any x86-64 host with these "
            "versions and glibc " + (platform.libc_ver()[1] or "?") + ")"
        )
    if not supported():
        return f"numerics: this host's ({platform.machine()} {platform.system()}): not pinned"
    why = "SERVO_AXIS_NUMERICS=native" if what == "native" else "not started in the pin"
    return f"numerics: this CPU's fastest paths ({why}): the last bits may differ on another host"


def _entry_point(argv: Sequence[str]) -> bool:
    """Whether the command line ``argv`` (``sys.orig_argv``) runs one of the package's entry points."""
    args = list(argv[1:])
    while args and args[0].startswith("-") and args[0] != "-m":
        # Interpreter options such as -u, -X dev, -W error.
        option = args.pop(0)
        if option in ("-X", "-W") and args:
            args.pop(0)
    if len(args) >= 2 and args[0] == "-m":
        # Not this package's own command line: it reports on, or starts, another process.
        module = args[1]
        if module == __name__ or module.startswith(f"{__name__}."):
            return False
        return module == "servo_axis" or module.startswith("servo_axis.")
    return bool(args) and os.path.basename(args[0]) == "servo-axis"


def enter() -> None:
    """Start this process again in the portable environment, if it runs an entry point.

    Called when the package is imported: it acts only where the process's
    command line is ``python -m servo_axis[.module]`` or the ``servo-axis``
    script, the environment is not pinned yet, and neither
    ``SERVO_AXIS_NUMERICS=native`` nor another platform says otherwise. A
    program that imports servo_axis as a library is never restarted (see
    :func:`main` for running one in the pin).
    """
    argv = getattr(sys, "orig_argv", [])
    if _entry_point(argv):
        restart(argv)


def restart(argv: Sequence[str] | None = None) -> None:
    """Start this process again (``argv``, default ``sys.orig_argv``) in the portable environment.

    Nothing happens where it is pinned already, where ``SERVO_AXIS_NUMERICS``
    is ``native``, or off x86-64 Linux. For a program that must compute the
    portable numbers in its own process (the test suite's ``conftest.py``,
    the measurement scripts): call it first, before numpy is imported
    (the process is replaced, so what it did before is lost).
    """
    if not supported() or os.environ.get(SWITCH, "portable") == "native":
        return
    if is_portable(os.environ):
        return
    argv = list(getattr(sys, "orig_argv", []) if argv is None else argv)
    env = portable_environment(os.environ)
    sys.stdout.flush()
    sys.stderr.flush()
    os.execve(sys.executable, [sys.executable, *argv[1:]], env)


def main(argv: Sequence[str] | None = None) -> int:
    """``python -m servo_axis.numerics [--env | --check | SCRIPT [ARGS]]``.

    ``SCRIPT [ARGS]`` runs a Python script in the portable environment (a
    new interpreter); ``--env`` prints the environment as ``export`` lines
    for a shell; ``--check`` prints :func:`describe` and the paths this
    process takes (:func:`servo_axis.numerics.state.active`), and exits 1
    unless they are the portable ones.
    """
    args = list(sys.argv[1:] if argv is None else argv)
    if not args or args[0] in ("-h", "--help"):
        print(main.__doc__)
        return 0 if args else 2
    if args[0] == "--env":
        env = portable_environment(os.environ)
        for key in (*PINNED, "GLIBC_TUNABLES"):
            if key in env:
                print(f"export {key}='{env[key]}'")
        return 0
    if args[0] == "--check":
        from servo_axis.numerics import state

        print(describe())
        paths = state.active()
        print("  " + ", ".join(f"{k}: {v}" for k, v in paths.items()))
        return 0 if is_portable(os.environ) and state.is_pinned(paths) else 1
    env = portable_environment(os.environ)
    os.execve(sys.executable, [sys.executable, *args], env)
    return 0  # pragma: no cover
