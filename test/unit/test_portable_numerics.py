"""The portable numeric environment: what it sets, who gets it, and that it holds.

The suite's own process runs in the pin (``servo_axis.numerics.pytest_plugin``,
loaded from pyproject.toml), as every node process of a run does; the
children started here with ``SERVO_AXIS_NUMERICS=native`` show that each
source really moves the numbers on this host, so that the identities under
the pin are not vacuous.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import textwrap

import numpy as np
import pytest

from servo_axis import numerics
from servo_axis.numerics import state

# Computations each source moves (measured on an AVX-512 host with FMA):
# libm's sin and exp, numpy's exp, an OpenBLAS matrix-vector product and expm.
# (numba's target moved no result of the suite's kernels: not probed, though pinned.)
PROBE = textwrap.dedent(
    """
    import json, math, sys
    import numpy as np, scipy.linalg
    x = np.linspace(0.1, 5.0, 4096)
    rng = np.random.default_rng(7)
    a = rng.standard_normal((8, 8))
    v = rng.standard_normal(8)
    out = {
        "libm": [math.sin(t / 10).hex() for t in x.tolist()] + [math.exp(t / 10).hex() for t in x.tolist()],
        "numpy": [t.hex() for t in np.exp(x).tolist()],
        "openblas": [t.hex() for t in (a @ (a @ v)).tolist()]
        + [t.hex() for t in scipy.linalg.expm(a / 4).ravel().tolist()],
    }
    json.dump(out, sys.stdout)
    """
)


def probe(env: dict[str, str]) -> dict[str, list[str]]:
    proc = subprocess.run(
        [sys.executable, "-c", PROBE], env=env, capture_output=True, text=True, check=True
    )
    return json.loads(proc.stdout)


def masked(base: dict[str, str], *names: str) -> dict[str, str]:
    env = dict(base)
    for name in names:
        for key, value in numerics.MASKS[name].items():
            env[key] = f"{env[key]}:{value}" if key == "GLIBC_TUNABLES" and env.get(key) else value
    return env


def test_the_suite_itself_runs_in_the_pin() -> None:
    # Not only the variables: what each library made of them.
    assert numerics.is_portable(os.environ)
    paths = state.active()
    assert paths == {
        "numpy": "baseline",
        "libm": "SSE2",
        "openblas": "numpy Nehalem/1, scipy Nehalem/1",
        "numba": "generic",
    }
    assert state.is_pinned(paths)


def test_the_pinned_numpy_targets_are_the_installed_numpys() -> None:
    from numpy._core._multiarray_umath import __cpu_baseline__, __cpu_dispatch__

    # A numpy of requirements.lock with other targets must change the pin.
    assert tuple(__cpu_dispatch__) == numerics.NUMPY_DISPATCH
    assert __cpu_baseline__ == ["X86_V2"]


def test_the_environment_overrides_a_hand_set_value_and_keeps_other_tunables() -> None:
    env = numerics.portable_environment(
        {
            "OPENBLAS_CORETYPE": "Haswell",
            "NPY_DISABLE_CPU_FEATURES": "X86_V4",
            "GLIBC_TUNABLES": "glibc.malloc.check=3:glibc.cpu.hwcaps=-AVX512F",
            "PATH": "/bin",
        }
    )
    assert env["OPENBLAS_CORETYPE"] == "Nehalem"
    assert env["OPENBLAS_NUM_THREADS"] == "1"
    assert env["NPY_DISABLE_CPU_FEATURES"] == "X86_V3 X86_V4 AVX512_ICL AVX512_SPR"
    assert env["NUMBA_CPU_NAME"] == "generic"
    assert env["GLIBC_TUNABLES"] == (
        "glibc.malloc.check=3:glibc.cpu.hwcaps=-AVX512F,-AVX,-AVX2,-FMA,-FMA4"
    )
    assert env["PATH"] == "/bin"
    assert numerics.is_portable(env)
    # Pinning twice changes nothing.
    assert numerics.portable_environment(env) == env


def test_native_leaves_the_environment_as_it_is() -> None:
    given = {"SERVO_AXIS_NUMERICS": "native", "OPENBLAS_CORETYPE": "Haswell"}
    assert numerics.portable_environment(given) == given
    assert not numerics.is_portable(given)
    assert numerics.mode(given) == "native"
    assert numerics.mode({}) == "host"
    assert "fastest paths" in numerics.describe(given)


@pytest.mark.parametrize(
    ("argv", "entry"),
    [
        (["python", "-m", "servo_axis", "run", "x"], True),
        (["python", "-m", "servo_axis.nodes.plant", "--ros-args"], True),
        (["python", "-u", "-X", "dev", "-m", "servo_axis", "list"], True),
        (["python", "/venv/bin/servo-axis", "list"], True),
        (["python", "-m", "servo_axis.numerics", "--check"], False),
        (["python", "-m", "servo_axisx"], False),
        (["python", "-m", "pytest", "test/unit"], False),
        (["python", "my_script.py"], False),
        (["python", "-c", "import servo_axis"], False),
        (["python"], False),
    ],
)
def test_only_the_packages_entry_points_start_again(argv: list[str], entry: bool) -> None:
    assert numerics._entry_point(argv) is entry


def test_an_entry_point_starts_in_the_pin_and_a_library_import_does_not() -> None:
    env = {k: v for k, v in os.environ.items() if k not in (*numerics.PINNED, "GLIBC_TUNABLES")}
    code = "import os, servo_axis; print(os.environ.get('OPENBLAS_CORETYPE'))"
    library = subprocess.run(
        [sys.executable, "-c", code], env=env, capture_output=True, text=True, check=True
    )
    assert library.stdout.strip() == "None"
    # python -m servo_axis.numerics SCRIPT: a program of one's own in the pin.
    entry = subprocess.run(
        [sys.executable, "-m", "servo_axis.numerics", "-c", code],
        env=env,
        capture_output=True,
        text=True,
        check=True,
    )
    assert entry.stdout.strip() == "Nehalem"
    # The package's command line starts again in it, arguments and output intact.
    check = subprocess.run(
        [sys.executable, "-m", "servo_axis", "numerics-probe-not-a-command"],
        env=env,
        capture_output=True,
        text=True,
        check=False,
    )
    assert check.returncode == 2 and "numerics-probe-not-a-command" in check.stderr
    shown = subprocess.run(
        [sys.executable, "-X", "importtime", "-m", "servo_axis", "list"],
        env=env,
        capture_output=True,
        text=True,
        check=True,
    )
    # Two interpreters: the first stops at servo_axis.numerics (no numpy), the second runs.
    first, found, second = shown.stderr.partition("servo_axis.numerics\n")
    assert found and "numpy" not in first and "numpy" in second


def test_the_pin_holds_under_the_masks_that_move_the_native_numbers() -> None:
    base = {k: v for k, v in os.environ.items() if k not in (*numerics.PINNED, "GLIBC_TUNABLES")}
    # A mask is what another machine would choose; the launcher pins over it.
    reference = probe(numerics.portable_environment(base))
    assert probe(numerics.portable_environment(masked(base, *numerics.MASKS))) == reference
    native = {**base, "SERVO_AXIS_NUMERICS": "native"}
    host = probe(native)
    code = "import json; from servo_axis.numerics import state; print(json.dumps(state.active()))"
    paths = json.loads(
        subprocess.run(
            [sys.executable, "-c", code], env=native, capture_output=True, text=True, check=True
        ).stdout
    )
    # Which source a mask can move depends on what this CPU has; where the
    # host's path is not the pinned one, its mask must move the numbers (or
    # the identity above proves nothing for it).
    expect = {
        "libm": paths["libm"] == "FMA",
        "numpy": "X86_V4" in paths["numpy"],
        "openblas": "Haswell" not in paths["openblas"] and "Nehalem" not in paths["openblas"],
    }
    for name, moves in expect.items():
        if moves:
            assert probe(masked(native, name))[name] != host[name], name
    if not any(expect.values()):
        # A CPU without FMA or AVX-512 whose OpenBLAS kernels are Nehalem's
        # (measured above): the identity holds, but no mask moved anything.
        pytest.skip(f"this host takes the pinned paths already, no mask can move them: {paths}")


def test_a_pinned_run_of_the_core_loop_is_the_same_under_every_mask(tmp_path) -> None:
    # The plain-call loop of a scenario with a sinusoidal disturbance (libm)
    # and matrices (OpenBLAS), a child per mask.
    code = textwrap.dedent(
        """
        import sys, numpy as np
        from servo_axis.params.scenario import scenario_dir
        from servo_axis.simulate import simulate
        t = simulate(scenario_dir() / "pid_disturbance.yaml", steps=1000)
        sys.stdout.write(np.stack([t.encoder_rad, t.command_Nm]).tobytes().hex())
        """
    )
    base = {k: v for k, v in os.environ.items() if k not in (*numerics.PINNED, "GLIBC_TUNABLES")}

    def run(env: dict[str, str]) -> str:
        return subprocess.run(
            [sys.executable, "-c", code], env=env, capture_output=True, text=True, check=True
        ).stdout

    here = run(numerics.portable_environment(base))
    assert run(numerics.portable_environment(masked(base, *numerics.MASKS))) == here
    from servo_axis.params.scenario import scenario_dir
    from servo_axis.simulate import simulate

    # ... and this process, pinned by the plugin, computes the same.
    t = simulate(scenario_dir() / "pid_disturbance.yaml", steps=1000)
    assert np.stack([t.encoder_rad, t.command_Nm]).tobytes().hex() == here
