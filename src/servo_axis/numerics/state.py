"""Which numeric paths this process takes, read from the libraries themselves.

:mod:`servo_axis.numerics` sets the environment; this module asks the loaded
libraries what they made of it: numpy's dispatch table, OpenBLAS's kernel
set and thread count, numba's target, and libm's variant by known answers
(an argument whose SSE2 and FMA results differ in the last bit, measured on
glibc 2.36). It imports numpy, so it is for a process that computes (a
node, a test, ``python -m servo_axis.numerics --check``), not for the
launcher.
"""

from __future__ import annotations

import ctypes
from pathlib import Path

from servo_axis.numerics import NUMPY_DISPATCH

#: ``(function, argument, result of the SSE2 variant, result of the FMA
#: variant)`` of glibc 2.36's libm, as ``float.hex``.
LIBM_ANSWERS = (
    ("sin", 0.1674701, "0x1.5560b79175e14p-3", "0x1.5560b79175e13p-3"),
    ("exp", 0.3317437, "0x1.64b594385d51ap+0", "0x1.64b594385d51bp+0"),
)

#: The OpenBLAS libraries of the numpy and scipy wheels and their functions.
_OPENBLAS = (
    (
        "numpy",
        "scipy_openblas64_",
        "scipy_openblas_get_corename64_",
        "scipy_openblas_get_num_threads64_",
    ),
    ("scipy", "scipy_openblas-", "scipy_openblas_get_corename", "scipy_openblas_get_num_threads"),
)


def numpy_paths() -> str:
    """numpy's dispatched targets in use: ``baseline`` or their names."""
    from numpy._core._multiarray_umath import __cpu_features__

    on = [t for t in NUMPY_DISPATCH if __cpu_features__.get(t)]
    return "baseline" if not on else " ".join(on)


def libm_variant() -> str:
    """``SSE2``, ``FMA`` or ``unknown`` (another libm than glibc 2.36's), by known answers."""
    import math

    got = [getattr(math, name)(x).hex() for name, x, _, _ in LIBM_ANSWERS]
    if got == [sse2 for *_, sse2, _ in LIBM_ANSWERS]:
        return "SSE2"
    if got == [fma for *_, fma in LIBM_ANSWERS]:
        return "FMA"
    return "unknown"


def openblas_cores() -> dict[str, str]:
    """``{"numpy": "Nehalem/1", "scipy": ...}``: each loaded OpenBLAS's kernels and threads."""
    import numpy  # noqa: F401  (loads numpy's OpenBLAS)
    import scipy.linalg  # noqa: F401  (and scipy's)

    maps = Path("/proc/self/maps")
    paths = (
        {line.split()[-1] for line in maps.read_text().splitlines() if "openblas" in line}
        if maps.exists()
        else set()
    )
    out: dict[str, str] = {}
    for owner, stem, corename, threads in _OPENBLAS:
        for path in sorted(paths):
            if stem in Path(path).name:
                lib = ctypes.CDLL(path)
                name = getattr(lib, corename)
                name.restype = ctypes.c_char_p
                out[owner] = f"{name().decode()}/{getattr(lib, threads)()}"
    return out


def numba_target() -> str:
    """The CPU numba compiles for (``generic`` in the pin)."""
    from numba.core import config

    return getattr(config, "CPU_NAME", None) or "host"


def active() -> dict[str, str]:
    """Every source at once: ``{"numpy": ..., "libm": ..., "openblas": ..., "numba": ...}``."""
    cores = openblas_cores()
    return {
        "numpy": numpy_paths(),
        "libm": libm_variant(),
        "openblas": ", ".join(f"{k} {v}" for k, v in cores.items()) or "not loaded",
        "numba": numba_target(),
    }


def is_pinned(paths: dict[str, str]) -> bool:
    """Whether :func:`active`'s ``paths`` are the portable ones."""
    return (
        paths["numpy"] == "baseline"
        and paths["libm"] == "SSE2"
        and paths["openblas"] == "numpy Nehalem/1, scipy Nehalem/1"
        and paths["numba"] == "generic"
    )
