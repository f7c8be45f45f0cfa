"""Clean-up of the shared-memory files a SIGKILLed Fast DDS participant leaves."""

from __future__ import annotations

import fcntl
import os
import time
from pathlib import Path

from servo_axis.run.processes import clean_stale_shm


def test_only_stale_files_of_this_run_are_removed(tmp_path: Path) -> None:
    since = time.time() - 10

    def make(*names: str, mtime: float | None = None) -> None:
        for name in names:
            path = tmp_path / name
            path.write_bytes(b"x")
            if mtime is not None:
                os.utime(path, (mtime, mtime))

    make("fastrtps_live", "fastrtps_live_el")  # its owner holds the lock
    make("fastrtps_dead", "fastrtps_dead_el", "sem.fastrtps_dead_mutex")  # owner gone
    make("fastrtps_port7005_el")  # lock file whose segment is gone
    make("fastrtps_port7011")  # port segment without a lock file
    make("fastrtps_old", "fastrtps_old_el", mtime=since - 3600)  # before this run
    owner = os.open(tmp_path / "fastrtps_live_el", os.O_RDWR)
    fcntl.flock(owner, fcntl.LOCK_EX)
    try:
        removed = clean_stale_shm(since=since, shm_dir=tmp_path)
    finally:
        os.close(owner)
    assert sorted(removed) == ["fastrtps_dead", "fastrtps_port7005", "fastrtps_port7011"]
    assert sorted(p.name for p in tmp_path.iterdir()) == [
        "fastrtps_live",
        "fastrtps_live_el",
        "fastrtps_old",
        "fastrtps_old_el",
    ]


def test_while_a_run_goes_on_only_segments_of_dead_owners_are_removed(tmp_path: Path) -> None:
    since = time.time() - 10
    for name in ("fastrtps_live", "fastrtps_live_el", "fastrtps_port7413", "fastrtps_port7413_el"):
        (tmp_path / name).write_bytes(b"x")
    (tmp_path / "sem.fastrtps_port7413_mutex").write_bytes(b"x")
    (tmp_path / "fastrtps_port7411").write_bytes(b"x")  # a live sender's: no lock file
    owner = os.open(tmp_path / "fastrtps_live_el", os.O_RDWR)
    fcntl.flock(owner, fcntl.LOCK_EX)
    try:
        removed = clean_stale_shm(since=since, shm_dir=tmp_path, dead_owners_only=True)
    finally:
        os.close(owner)
    # The dead participant's receive port goes, so that the participant that
    # replaces it (same id, same port) makes a fresh one.
    assert removed == ["fastrtps_port7413"]
    assert sorted(p.name for p in tmp_path.iterdir()) == [
        "fastrtps_live",
        "fastrtps_live_el",
        "fastrtps_port7411",
    ]
