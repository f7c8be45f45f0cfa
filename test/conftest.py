"""Shared fixtures: an isolated ROS environment per test."""

from __future__ import annotations

import contextlib
import itertools
import os
import time
import warnings
from collections.abc import Callable, Iterator
from pathlib import Path

import pytest

# Before any test loads numpy: one BLAS thread, as the suite's own processes.
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

REPO = Path(__file__).resolve().parents[1]
CONFIG = REPO / "config"

# Each test that touches ROS gets its own domain; the base depends on the pid
# so that two suites on one machine are unlikely to collide.
# SERVO_AXIS_TEST_DOMAINS=LO-HI confines a suite to domains LO..HI (inclusive),
# so that suites run side by side (two checkouts) never share one; the
# workers of one suite under pytest-xdist split it among themselves.
_domains = itertools.count()


def _domain_range() -> tuple[int, int]:
    given = os.environ.get("SERVO_AXIS_TEST_DOMAINS", "")
    if not given:
        return 10, 99
    try:
        low, high = (int(part) for part in given.split("-"))
    except ValueError:
        raise pytest.UsageError(
            f"SERVO_AXIS_TEST_DOMAINS: expected LO-HI (two domain ids), got {given!r}"
        ) from None
    if not 0 <= low <= high <= 232:
        raise pytest.UsageError(
            f"SERVO_AXIS_TEST_DOMAINS: expected 0 <= LO <= HI <= 232, got {given!r}"
        )
    return low, high


def _worker_range(low: int, high: int) -> tuple[int, int]:
    """This pytest-xdist worker's share of ``low..high``: workers never share a domain.

    ``gwK`` of ``N`` workers takes the K-th of N equal, disjoint slices (the
    whole range without xdist).
    """
    worker = os.environ.get("PYTEST_XDIST_WORKER", "")
    if not worker:
        return low, high
    count = int(os.environ.get("PYTEST_XDIST_WORKER_COUNT", "1"))
    index = int(worker.removeprefix("gw"))
    size = (high - low + 1) // count
    if size < 1:
        raise pytest.UsageError(
            f"SERVO_AXIS_TEST_DOMAINS: {high - low + 1} domains for {count} pytest-xdist "
            "workers; expected at least one each"
        )
    return low + index * size, low + (index + 1) * size - 1


_LOW, _HIGH = _domain_range()
_START = (os.getpid() % 9) * 10


def next_domain_id() -> int:
    # The worker's slice is asked for here, not at import: test/unit on many
    # workers needs no domain, whatever the range.
    low, high = _worker_range(_LOW, _HIGH)
    return low + (_START + next(_domains)) % (high - low + 1)


@contextlib.contextmanager
def _isolated_ros(monkeypatch: pytest.MonkeyPatch, log_dir: Path, what: str) -> Iterator[int]:
    """A fresh domain, localhost discovery, UDP only and ``log_dir`` as ROS_LOG_DIR.

    Set with ``monkeypatch`` (which restores them); Fast DDS shared memory
    made meanwhile and left behind is removed and named in a warning (``what``).
    """
    domain = next_domain_id()
    monkeypatch.setenv("ROS_DOMAIN_ID", str(domain))
    monkeypatch.setenv("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")
    monkeypatch.setenv("FASTDDS_BUILTIN_TRANSPORTS", "UDPv4")
    log_dir.mkdir()
    monkeypatch.setenv("ROS_LOG_DIR", str(log_dir))
    # The in-test probes use the nodes' discovery profile (restored after).
    from servo_axis.run.processes import ros_environment

    profile = ros_environment(domain, log_dir)["FASTRTPS_DEFAULT_PROFILES_FILE"]
    monkeypatch.setenv("FASTRTPS_DEFAULT_PROFILES_FILE", profile)
    started = time.time()
    yield domain
    # What a test started must not outlive it, shared memory included: a
    # participant killed by a test (or by a timeout) leaves its Fast DDS
    # files behind. They are removed here and named, so a leak is seen.
    from servo_axis.run.fastdds import clean_stale_shm

    left = clean_stale_shm(since=started)
    for _ in range(4 if left else 0):
        # A killed participant's peers may still be exiting (their locks held a
        # little longer than their pids are listed): their files go once they are.
        time.sleep(0.25)
        left += clean_stale_shm(since=started)
    if left:
        warnings.warn(f"{what} left Fast DDS shared memory behind (removed): {left}", stacklevel=1)


_SESSION_STARTED = time.time()


def pytest_sessionfinish(session: pytest.Session, exitstatus: int) -> None:
    """Remove what dead participants of this session left in /dev/shm.

    A test's teardown removes only segments whose owner is gone by then; a
    node that a SIGKILLed runner takes down (PR_SET_PDEATHSIG) may still hold
    its lock at that moment and leave its files once it dies (118 were found
    after a day of suites). Dead owners only: other suites may be running.
    """
    from servo_axis.run.fastdds import clean_stale_shm

    clean_stale_shm(since=_SESSION_STARTED, dead_owners_only=True)


def pytest_sessionstart(session: pytest.Session) -> None:
    """Remove what dead participants of earlier sessions left (the last test's nodes
    may outlive the finish above by the interpreter's exit)."""
    from servo_axis.run.fastdds import clean_stale_shm

    clean_stale_shm(since=0.0, dead_owners_only=True)


@pytest.fixture
def ros_env(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, request: pytest.FixtureRequest
) -> Iterator[int]:
    """Distinct ROS_DOMAIN_ID, localhost discovery, UDP only, temporary ROS_LOG_DIR.

    Everything it sets is restored when the test ends.
    """
    with _isolated_ros(monkeypatch, tmp_path / "ros_log", request.node.nodeid) as domain:
        yield domain


@pytest.fixture
def more_domains(ros_env: int) -> Callable[[], int]:
    """Fresh ROS domains of the worker's slice beside ``ros_env``'s (with its isolation),
    for runs a test starts side by side, each in a domain of its own."""
    return next_domain_id


@pytest.fixture(scope="module")
def module_ros_env(
    tmp_path_factory: pytest.TempPathFactory, request: pytest.FixtureRequest
) -> Iterator[tuple[int, Path]]:
    """``ros_env`` for the runs a module's tests share: ``(domain, a folder for the runs)``.

    A run that several tests read is made once (in a module-scoped fixture
    of the test module) instead of once per test.
    """
    folder = tmp_path_factory.mktemp(request.module.__name__.rsplit(".", 1)[-1])
    with (
        pytest.MonkeyPatch.context() as monkeypatch,
        _isolated_ros(monkeypatch, folder / "ros_log", request.module.__name__) as domain,
    ):
        yield domain, folder


def read_raw_payloads(bag_dir: Path) -> dict[str, list[bytes]]:
    """CDR payloads per topic, in publication order, read with the mcap library.

    Every MCAP file ``metadata.yaml`` lists (a split bag has several), in
    order; a topic's messages in the order of the files, then of their
    sequence numbers.
    """
    import yaml
    from mcap.reader import make_reader

    meta = bag_dir / "metadata.yaml"
    if meta.is_file():
        names = yaml.safe_load(meta.read_text())["rosbag2_bagfile_information"][
            "relative_file_paths"
        ]
    else:  # a bag never closed: its one file
        (only,) = bag_dir.glob("*.mcap")
        names = [only.name]
    out: dict[str, list[tuple[int, int, bytes]]] = {}
    for index, name in enumerate(names):
        with (bag_dir / name).open("rb") as f:
            for _schema, channel, message in make_reader(f).iter_messages():
                out.setdefault(channel.topic, []).append((index, message.sequence, message.data))
    return {t: [d for _, _, d in sorted(v)] for t, v in out.items()}


@pytest.fixture
def raw_payloads() -> Callable[[Path], dict[str, list[bytes]]]:
    """The bag reader for payload comparisons (independent of servo_axis)."""
    return read_raw_payloads


def install_package(package: Path, site: Path) -> None:
    """What ``pip install --target site package`` leaves: its modules and a ``*.dist-info``.

    The modules of ``package/src`` are copied, and the dist-info gets the
    name, version and entry points of its ``pyproject.toml``, which
    ``importlib.metadata`` reads from a folder on ``sys.path`` (in a
    subprocess with ``PYTHONPATH=site``) as from any installed package.
    Instant, where pip builds a wheel first.
    """
    import shutil
    import tomllib

    project = tomllib.loads((package / "pyproject.toml").read_text())["project"]
    for module in (package / "src").iterdir():
        shutil.copytree(module, site / module.name)
    info = site / f"{project['name'].replace('-', '_')}-{project['version']}.dist-info"
    info.mkdir()
    (info / "METADATA").write_text(
        f"Metadata-Version: 2.1\nName: {project['name']}\nVersion: {project['version']}\n"
    )
    (info / "entry_points.txt").write_text(
        "".join(
            f"[{group}]\n" + "".join(f"{name} = {value}\n" for name, value in points.items()) + "\n"
            for group, points in project["entry-points"].items()
        )
    )


@pytest.fixture(scope="session")
def broken_plugin_site(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A folder with ``test/data/broken_plugin`` installed (put it on PYTHONPATH of a subprocess)."""
    site = tmp_path_factory.mktemp("broken_plugin_site")
    install_package(REPO / "test" / "data" / "broken_plugin", site)
    return site


#: The modules of the longest runs of work one pytest-xdist worker cannot
#: share (``--dist loadfile``: a module is one unit), longest first (a serial
#: ``pytest test/ros test/integration --durations=0``); the order only.
_LONGEST_FIRST = (
    "test_docs_pages",
    "test_external",
    "test_determinism",
    "test_elastic_runs",
    "test_runs",
    "test_dlpid_runs",
    "test_learning",
    "test_outside_plant",
    "test_ilc_runs",
    "test_live",
    "test_bad_params",
    "test_node_deaths",
    "test_junk",
)


@pytest.hookimpl(tryfirst=True)
def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    """Under pytest-xdist the longest modules first, so that none is left for the end.

    ``scripts/test.sh`` keeps this order (``--no-loadscope-reorder``).
    Without xdist the order stays the collection's.
    """
    # Under xdist the order that counts is the workers' (the controller sends
    # them the modules in it), and a worker's own options say dist "no".
    if getattr(config.option, "dist", "no") == "no" and not hasattr(config, "workerinput"):
        return

    def rank(item: pytest.Item) -> int:
        name = item.module.__name__.rsplit(".", 1)[-1] if item.module is not None else ""
        return _LONGEST_FIRST.index(name) if name in _LONGEST_FIRST else len(_LONGEST_FIRST)

    items.sort(key=rank)
