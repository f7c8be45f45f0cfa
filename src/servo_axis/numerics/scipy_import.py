"""scipy in a node process, without numpy's ``f2py`` and ``testing``.

scipy (1.15 and later) bundles array-api-compat, whose numpy namespace is a
copy of numpy's, made on the first import of any scipy subpackage (the
plant's ``scipy.linalg.expm``, numba's BLAS check when it loads a kernel):
``from numpy import *`` and a ``getattr`` of every name ``dir(numpy)`` lists.
Both lists name numpy's lazily imported submodules, so ``numpy.f2py`` and
``numpy.testing`` are imported as well, which nothing on scipy's numpy path
uses (its ``xp.testing`` is CuPy's and PyTorch's): 0.10 to 0.14 s of CPU of
the ~0.5 s that ``import scipy.linalg`` costs (``python -c "import numpy;
import scipy.linalg"``: 0.52-0.54 s; with the copy made as here,
0.39-0.47 s). A run starts its plant and feedforward processes with scipy,
and the suite starts hundreds of runs.

:func:`install` makes the copy, when scipy makes it, with those two names
left out of numpy's ``__all__`` and ``dir()`` for the moment of the copy
only; nothing is imported until scipy is, numpy is the same before and
after, and no number changes (the two modules compute nothing a run uses).
"""

from __future__ import annotations

import importlib.abc
import importlib.machinery
import sys
from collections.abc import Sequence
from types import ModuleType

__all__ = ["install"]

#: numpy's submodules that scipy's copy of numpy's namespace does not need.
NOT_COPIED = frozenset({"f2py", "testing"})

#: The scipy module whose import copies numpy's namespace.
COPYING_MODULE = "scipy._lib.array_api_compat.numpy"


class _Loader(importlib.abc.Loader):
    """The copying module's own loader, run with numpy's lists shortened."""

    def __init__(self, inner: importlib.abc.Loader) -> None:
        self._inner = inner

    def create_module(self, spec: importlib.machinery.ModuleSpec) -> ModuleType | None:
        return self._inner.create_module(spec)

    def exec_module(self, module: ModuleType) -> None:
        import numpy as np

        listed, names = np.__dir__, np.__all__
        np.__dir__ = lambda: [n for n in listed() if n not in NOT_COPIED]  # type: ignore[method-assign]
        np.__all__ = [n for n in names if n not in NOT_COPIED]
        try:
            self._inner.exec_module(module)
        finally:
            np.__dir__ = listed  # type: ignore[method-assign]
            np.__all__ = names


class _Finder(importlib.abc.MetaPathFinder):
    """Finds the copying module once, then leaves ``sys.meta_path``."""

    def find_spec(
        self, fullname: str, path: Sequence[str] | None, target: ModuleType | None = None
    ) -> importlib.machinery.ModuleSpec | None:
        if fullname != COPYING_MODULE:
            return None
        sys.meta_path.remove(self)
        spec = importlib.machinery.PathFinder.find_spec(fullname, path)
        if spec is None or spec.loader is None:
            return spec
        spec.loader = _Loader(spec.loader)
        return spec


def install() -> None:
    """From now on in this process, scipy's copy of numpy's namespace skips ``f2py`` and ``testing``.

    Does nothing once the copy is made (or either module is loaded), or if
    it is installed already.
    """
    if COPYING_MODULE in sys.modules or any(f"numpy.{n}" in sys.modules for n in NOT_COPIED):
        return
    if not any(isinstance(f, _Finder) for f in sys.meta_path):
        sys.meta_path.insert(0, _Finder())
