"""Running a study on dask.distributed: manifest, results table, figures, progress.

The points go to a ``LocalCluster`` (one single-threaded worker process per
core: the loops are numpy) or to an existing scheduler. A point that fails
is a row with its error; a worker that dies has its points rerun on another
(the scheduler does that; the client waits for them). Every finished row is
written to ``manifest.json`` at once, so a study that is stopped and started
again with the same ``--out`` runs only the points it has not finished.
Workers whose package versions differ from the client's are refused.

Ctrl-C stops a study cleanly: the LocalCluster's workers ignore SIGINT (the
terminal sends it to the whole process group; the client closes them), the
finished rows stay in the manifest, ``results.csv`` is written with the rest
marked ``not run``, and the line printed says how to resume. A corrected
figure path is not another study: the points run again (a ``nodes`` point's
figures are read again from its run's ``summary.json``).
"""

from __future__ import annotations

import contextlib
import json
import logging
import math
import os
import re
import signal
import subprocess
import sys
import threading
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

from servo_axis.sweep.point import cell, run_point
from servo_axis.sweep.spec import Study, StudyError, figure

MANIFEST = "manifest.json"
RESULTS = "results"  # results.parquet, results.csv
COLUMNS_AFTER = ("status", "error", "wall_time_s")
#: The status of a point an interrupted study did not finish (``results.csv`` only).
NOT_RUN = "not run"
#: How long a client waits for a ``--scheduler`` that does not answer (s).
CONNECT_TIMEOUT_S = 30.0


class VersionMismatchError(RuntimeError):
    """A worker runs other package versions than the client."""


def versions() -> dict[str, str]:
    """The versions a result depends on: servo_axis (+ git commit), numpy, scipy, numba, Python."""
    import numba
    import numpy
    import scipy

    import servo_axis

    here = Path(servo_axis.__file__).resolve().parent
    commit = ""
    with contextlib.suppress(OSError, subprocess.SubprocessError):
        proc = subprocess.run(
            ["git", "-C", str(here), "rev-parse", "HEAD"],
            capture_output=True,
            text=True,
            timeout=10,
            check=False,
        )
        commit = proc.stdout.strip() if proc.returncode == 0 else ""
    return {
        "servo_axis": servo_axis.__version__ + (f"+{commit[:12]}" if commit else ""),
        "numpy": numpy.__version__,
        "scipy": scipy.__version__,
        "numba": numba.__version__,
        "python": ".".join(map(str, sys.version_info[:3])),
    }


def check_workers(client: Any) -> int:
    """Refuse workers whose :func:`versions` differ from the client's; return their number."""
    mine = versions()
    theirs = client.run(versions)
    if not theirs:
        raise VersionMismatchError("the scheduler has no workers")
    for address, found in sorted(theirs.items()):
        differ = [f"{k} {found.get(k)} (client {v})" for k, v in mine.items() if found.get(k) != v]
        if differ:
            raise VersionMismatchError(
                f"worker {address} refused: its versions differ from the client's: "
                f"{', '.join(differ)}; install the same lock file (requirements.lock) there"
            )
    return len(theirs)


def _write_json(path: Path, data: Any) -> None:
    tmp = path.with_suffix(".tmp")
    tmp.write_text(json.dumps(data, indent=1, sort_keys=False, default=str))
    os.replace(tmp, path)


def _load_manifest(out: Path, study: Study) -> dict[str, dict[str, Any]]:
    """The finished rows of an earlier run of ``study`` in ``out`` (none if there is none).

    A manifest of the same points whose figures differ (a path corrected
    after a run) is the same study: a ``nodes`` point whose run directory
    still holds its ``summary.json`` has its figures picked again from it,
    every other point runs again.
    """
    path = out / MANIFEST
    if not path.is_file():
        return {}
    data = json.loads(path.read_text())
    rows = {str(k): v for k, v in data.get("rows", {}).items()}
    if data.get("fingerprint") == study.fingerprint():
        return rows
    runs = data.get("runs_fingerprint")
    if runs is None or runs != study.runs_fingerprint():
        raise StudyError(
            f"study {study.name}: {out} holds another study's results "
            f"(fingerprint {data.get('fingerprint')}, this one {study.fingerprint()}); "
            "use another --out"
        )
    old_figures = set(data.get("figures") or {})
    kept = {}
    for key, row in rows.items():
        summary_file = out / "runs" / f"point_{int(key):05d}" / "summary.json"
        if study.backend != "nodes" or row.get("status") != "ok" or not summary_file.is_file():
            continue
        summary = json.loads(summary_file.read_text())
        try:
            values = {n: cell(figure(summary, w)) for n, w in study.figures.items()}
        except KeyError:
            continue  # runs again, and fails with the figure's error as a row
        kept[key] = {
            **{c: v for c, v in row.items() if c not in old_figures and c not in COLUMNS_AFTER},
            **values,
            **{c: row.get(c) for c in COLUMNS_AFTER},
        }
    print(
        f"study {study.name}: the figures differ from those of {out}; "
        f"{len(kept)} finished point(s) read again from their runs, "
        f"{len(study.points) - len(kept)} to run",
        file=sys.stderr,
    )
    return kept


@contextlib.contextmanager
def _quiet_sigint() -> Iterator[None]:
    """SIGINT ignored while the block starts processes: they inherit it and ignore Ctrl-C.

    The terminal sends Ctrl-C to the whole process group; the client alone
    handles it (and closes the workers), so no worker prints a traceback.
    """
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    previous = signal.signal(signal.SIGINT, signal.SIG_IGN)
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, previous)


@contextlib.contextmanager
def _client(
    scheduler: str | None, workers: int | None, connect_timeout_s: float = CONNECT_TIMEOUT_S
) -> Iterator[Any]:
    from dask.distributed import Client, LocalCluster

    if scheduler:
        try:
            client = Client(scheduler, timeout=f"{connect_timeout_s}s")
        except (OSError, TimeoutError) as err:
            raise StudyError(
                f"--scheduler {scheduler}: no dask scheduler answered within "
                f"{connect_timeout_s:g} s ({err})"
            ) from err
        with client:
            yield client
        return
    n = workers or os.cpu_count() or 1
    with _quiet_sigint():
        cluster = LocalCluster(
            n_workers=n, threads_per_worker=1, processes=True, dashboard_address=None
        )
    with cluster, Client(cluster) as client:
        yield client


def _silence(client: Any) -> None:
    """Dask's own warnings off, here and on the workers, for a shutdown we asked for."""

    def quiet() -> None:
        for name in ("distributed", "tornado"):
            logging.getLogger(name).setLevel(logging.CRITICAL)

    quiet()
    with contextlib.suppress(Exception):
        client.run(quiet, wait=True)


def resume_command(study: Study, out: Path, scheduler: str | None) -> str:
    """The command that resumes ``study`` in ``out``."""
    where = study.source or study.name
    return f"python -m servo_axis sweep {where} --out {out}" + (
        f" --scheduler {scheduler}" if scheduler else ""
    )


def _clock(seconds: float) -> str:
    if not math.isfinite(seconds):
        return "--:--"
    m, s = divmod(round(seconds), 60)
    return f"{m // 60}:{m % 60:02d}:{s:02d}" if m >= 60 else f"{m}:{s:02d}"


def run_study(
    study: Study,
    out: Path,
    *,
    scheduler: str | None = None,
    workers: int | None = None,
    retry_failed: bool = False,
    plots: bool = True,
    progress: bool = True,
    connect_timeout_s: float = CONNECT_TIMEOUT_S,
) -> list[dict[str, Any]]:
    """Run the points a previous run of the study in ``out`` has not finished; write the results.

    Parameters
    ----------
    study : Study
        The checked study (:func:`servo_axis.sweep.spec.load_study`).
    out : Path
        The study's directory (``manifest.json``, ``results.parquet``,
        ``results.csv``, one PNG per figure and swept parameter).
    scheduler : str or None
        ``tcp://host:port`` of a running dask scheduler; None: a ``LocalCluster``.
    workers : int or None
        The LocalCluster's worker processes (one thread each); None: the cores.
    retry_failed : bool
        Run again the points the manifest has as failed.
    plots : bool
        Write the figures' PNGs.
    progress : bool
        Print a progress line (points done, failed, time left) on stderr.
    connect_timeout_s : float
        How long to wait for ``scheduler`` (s); ``out`` is made only once it answered.

    Returns
    -------
    list of dict
        The rows, in point order.

    Raises
    ------
    StudyError
        ``out`` holds another study, or the scheduler does not answer.
    KeyboardInterrupt
        After Ctrl-C, once the manifest and ``results.csv`` hold the finished
        points and the line that says how to resume is printed.
    """
    from dask.distributed import as_completed

    fingerprint = study.fingerprint()
    rows = _load_manifest(out, study)
    if retry_failed:
        rows = {k: r for k, r in rows.items() if r.get("status") == "ok"}
    manifest: dict[str, Any] = {
        "study": study.name,
        "fingerprint": fingerprint,
        "runs_fingerprint": study.runs_fingerprint(),
        "scenario": study.scenario,
        "backend": study.backend,
        "parameters": list(study.parameters),
        "figures": study.figures,
        "points": len(study.points),
        "versions": versions(),
        "rows": rows,
    }
    todo = [i for i in range(len(study.points)) if str(i) not in rows]
    run_root = str(out / "runs") if study.backend == "nodes" else None
    total, t0 = len(study.points), time.perf_counter()
    done_now = 0
    # The line is rewritten in place (\r): done, failed, elapsed and left.

    def report(final: bool = False) -> None:
        if not progress:
            return
        done = len(rows)
        failed = sum(r.get("status") != "ok" for r in rows.values())
        elapsed = time.perf_counter() - t0
        left = elapsed / done_now * (total - done) if done_now else math.inf
        line = (
            f"\rstudy {study.name}: {done}/{total} done, {failed} failed, "
            f"{_clock(elapsed)} elapsed, {_clock(0.0 if final else left)} left"
        )
        print(line, end="\n" if final else "", file=sys.stderr, flush=True)

    if todo:
        with _client(scheduler, workers, connect_timeout_s) as client:
            check_workers(client)
            out.mkdir(parents=True, exist_ok=True)
            t0 = time.perf_counter()
            report()
            futures = {
                client.submit(
                    run_point,
                    i,
                    study.scenario,
                    study.points[i],
                    study.figures,
                    study.backend,
                    run_root,
                    key=f"servo-axis-point-{fingerprint}-{i}",
                    pure=False,
                    retries=2,
                ): i
                for i in todo
            }
            try:
                for future in as_completed(futures):
                    i = futures[future]
                    try:
                        row = future.result()
                    except Exception as err:  # e.g. KilledWorker: died on too many workers
                        row = {
                            "point": i,
                            **{k: cell(v) for k, v in study.points[i].items()},
                            **dict.fromkeys(study.figures, math.nan),
                            "status": "failed",
                            "error": f"{type(err).__name__}: {err}",
                            "wall_time_s": math.nan,
                        }
                    rows[str(i)] = row
                    done_now += 1
                    _write_json(out / MANIFEST, manifest)
                    report()
            except KeyboardInterrupt:
                _silence(client)
                client.cancel(list(futures))
                _write_json(out / MANIFEST, manifest)
                ordered = [
                    _complete(rows.get(str(i)) or _not_run(i, study), study) for i in range(total)
                ]
                write_results(ordered, study, out)
                print(
                    f"\nstudy {study.name}: interrupted with {len(rows)} of {total} points "
                    f"finished ({out / MANIFEST}, {out / RESULTS}.csv); "
                    f"the same command resumes: {resume_command(study, out, scheduler)}",
                    file=sys.stderr,
                    flush=True,
                )
                raise
    out.mkdir(parents=True, exist_ok=True)
    _write_json(out / MANIFEST, manifest)
    report(final=True)
    ordered = [_complete(rows[str(i)], study) for i in range(total)]
    write_results(ordered, study, out)
    if plots:
        plot_figures(ordered, study, out)
    return ordered


def _not_run(i: int, study: Study) -> dict[str, Any]:
    """The row of a point an interrupted study did not finish."""
    return {
        "point": i,
        **{k: cell(v) for k, v in study.points[i].items()},
        "status": NOT_RUN,
        "error": "",
    }


def _complete(row: dict[str, Any], study: Study) -> dict[str, Any]:
    """A row with every column of the study, in the table's order."""
    columns = ["point", *study.parameters, *study.figures, *COLUMNS_AFTER]
    return {
        c: row.get(c, math.nan if c in study.figures or c == "wall_time_s" else None)
        for c in columns
    }


def write_results(rows: list[dict[str, Any]], study: Study, out: Path) -> None:
    """``results.parquet`` and ``results.csv``: one row per point."""
    import csv

    import pyarrow as pa
    import pyarrow.parquet as pq

    columns = list(rows[0])
    table = pa.table({c: pa.array([r[c] for r in rows]) for c in columns})
    pq.write_table(table, out / f"{RESULTS}.parquet")
    with (out / f"{RESULTS}.csv").open("w", newline="") as f:
        writer = csv.DictWriter(f, fieldnames=columns)
        writer.writeheader()
        for r in rows:
            writer.writerow({k: repr(v) if isinstance(v, float) else v for k, v in r.items()})


def _slug(text: str) -> str:
    return re.sub(r"[^\w.-]+", "_", text).strip("_")


def _splitting_keys(rows: list[dict[str, Any]], param: str, others: list[str]) -> list[str]:
    """The keys of ``others`` that tell rows apart beyond ``param`` and the keys kept before.

    A key that follows from the swept one (``sigmoid.enabled`` = not
    ``gms.enabled`` in ``reversal_004``) or from the others splits no line:
    grouping by it made one line per point, each a single marker under a
    legend of as many entries.
    """

    def kinds(keys: list[str]) -> int:
        return len({tuple(str(r.get(k)) for k in keys) for r in rows})

    kept: list[str] = []
    for key in others:
        if kinds([param, *kept, key]) > kinds([param, *kept]):
            kept.append(key)
    return kept


def plot_figures(rows: list[dict[str, Any]], study: Study, out: Path) -> list[Path]:
    """One PNG per figure and swept parameter (a line per combination of the other parameters)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from servo_axis.analysis.plots import plain_ticks
    from servo_axis.analysis.units import summary_quantity

    ok = [r for r in rows if r["status"] == "ok"]
    written = []
    for name in study.figures:
        for param in study.parameters:
            others = _splitting_keys(ok, param, [p for p in study.parameters if p != param])
            groups: dict[tuple[Any, ...], list[tuple[Any, float]]] = {}
            for r in ok:
                value = r[name]
                if not isinstance(value, int | float) or isinstance(value, bool):
                    continue
                groups.setdefault(tuple(r[p] for p in others), []).append((r[param], value))
            if not groups:
                continue
            merged = len(groups) > 1 and all(len(pts) == 1 for pts in groups.values())
            if merged:
                # No two points differ in this key alone: one set of markers, no lines.
                others = []
                groups = {(): [pt for pts in groups.values() for pt in pts]}
            fig, ax = plt.subplots(figsize=(6.5, 4))
            # In the unit of its quantity (um for a tracking error, rad on a rotary
            # table, ...), as every table and figure of a run; a ratio as it is.
            quantity = summary_quantity(study.figures[name])
            factor = 1.0 if quantity is None else quantity.factor
            numeric = all(
                isinstance(x, int | float) and not isinstance(x, bool)
                for pts in groups.values()
                for x, _ in pts
            )
            style = "o" if merged else "o-"
            for key, pts in groups.items():
                pts.sort(key=lambda p: p[0] if numeric else str(p[0]))
                xs = [p[0] if numeric else str(p[0]) for p in pts]
                label = ", ".join(f"{p}={v}" for p, v in zip(others, key, strict=True)) or None
                ax.plot(xs, [factor * p[1] for p in pts], style, label=label)
            ax.set_xlabel(param)
            ax.set_ylabel(name if quantity is None else quantity.label(name))
            plain_ticks(ax)
            ax.set_title(f"{study.name}: {name}", fontsize=9)
            ax.grid(True, alpha=0.4)
            if others and len(groups) <= 12:
                ax.legend(fontsize=7)
            fig.tight_layout()
            path = out / f"{_slug(name)}__vs__{_slug(param)}.png"
            fig.savefig(path, dpi=100)
            plt.close(fig)
            written.append(path)
    return written
