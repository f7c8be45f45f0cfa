"""Clean-up of the shared-memory files a SIGKILLed Fast DDS participant leaves; restart ids."""

from __future__ import annotations

import fcntl
import os
import socket
import subprocess
import sys
import time
from pathlib import Path
from xml.etree import ElementTree

import pytest

from servo_axis.run.fastdds import (
    REALTIME_ANNOUNCEMENT_S,
    RESTART_PARTICIPANT_IDS,
    clean_stale_shm,
    files_in_use,
    free_participant_id,
    participant_ports,
    realtime_profile,
    with_participant_id,
)
from servo_axis.run.processes import discovery_settings


def test_only_stale_files_of_this_run_are_removed(tmp_path: Path) -> None:
    since = time.time() - 10

    def make(*names: str, mtime: float = since + 1) -> None:
        # Made after `since`, older than LOCK_GRACE_S.
        for name in names:
            path = tmp_path / name
            path.write_bytes(b"x")
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


def test_a_lock_file_removed_while_it_is_looked_at_is_passed_over(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Its owner (or another run's clean-up) removes it between the listing and the look:
    the clean-up goes on with the others (it raised FileNotFoundError from a test's teardown)."""
    import servo_axis.run.fastdds as fastdds

    since = time.time() - 10
    for name in ("fastrtps_going", "fastrtps_going_el", "fastrtps_dead", "fastrtps_dead_el"):
        (tmp_path / name).write_bytes(b"x")
        os.utime(tmp_path / name, (since + 1, since + 1))
    looked_at = fastdds._lock_held

    def removed_meanwhile(lock: Path) -> bool:
        if lock.name == "fastrtps_going_el":
            lock.unlink()
            (tmp_path / "fastrtps_going").unlink()
        return looked_at(lock)

    monkeypatch.setattr(fastdds, "_lock_held", removed_meanwhile)
    assert clean_stale_shm(since=since, shm_dir=tmp_path) == ["fastrtps_dead"]
    assert list(tmp_path.iterdir()) == []


def test_while_a_run_goes_on_only_segments_of_dead_owners_are_removed(tmp_path: Path) -> None:
    since = time.time() - 10
    for name in ("fastrtps_live", "fastrtps_live_el", "fastrtps_port7413", "fastrtps_port7413_el"):
        (tmp_path / name).write_bytes(b"x")
        os.utime(tmp_path / name, (since + 1, since + 1))  # older than LOCK_GRACE_S
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


HOLDER = """
import mmap, os, sys
held = []
for path in sys.argv[2:]:
    fd = os.open(path, os.O_RDWR)
    if sys.argv[1] == "map":
        held.append(mmap.mmap(fd, 0))
        os.close(fd)  # the mapping alone keeps it in use, as Fast DDS's segments
    else:
        held.append(fd)
print("ready", flush=True)
sys.stdin.read()
"""


@pytest.mark.parametrize("how", ["map", "open"])
def test_what_a_live_process_holds_stays_unless_its_owner_died(tmp_path: Path, how: str) -> None:
    """Another run on the machine (a second pytest-xdist worker) may be between
    creating a segment and locking it, or send to a port that has no lock file:
    a port segment without a lock file stays while a live process has it mapped
    or open, a lock file nobody holds for LOCK_GRACE_S after it was made. A dead
    owner's segment goes even while a live peer maps it or its lock file."""
    since = time.time() - 60
    names = ["fastrtps_port7002", "fastrtps_abc", "fastrtps_abc_el", "fastrtps_port7011",
             "fastrtps_dead", "fastrtps_dead_el"]  # fmt: skip
    for name in names:
        (tmp_path / name).write_bytes(b"x" * 4096)
    old = time.time() - 30
    for name in ("fastrtps_port7011", "fastrtps_dead", "fastrtps_dead_el"):
        os.utime(tmp_path / name, (old, old))
    # A sender's port segment without a lock file; a dead owner's segment and
    # lock file that a live peer still has.
    held = ["fastrtps_port7002", "fastrtps_dead", "fastrtps_dead_el"]
    holder = subprocess.Popen(
        [sys.executable, "-c", HOLDER, how, *(str(tmp_path / name) for name in held)],
        stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True,
    )  # fmt: skip
    try:
        assert holder.stdout is not None and holder.stdout.readline() == "ready\n"
        assert set(held) <= files_in_use(tmp_path)
        removed = clean_stale_shm(since=since, shm_dir=tmp_path)
        # fastrtps_abc's lock file is new: its owner may not have locked it yet.
        assert removed == ["fastrtps_dead", "fastrtps_port7011"]
    finally:
        holder.communicate("", timeout=10)
    # Once its holder has gone, and once the lock file is older, all goes.
    os.utime(tmp_path / "fastrtps_abc_el", (old, old))
    assert sorted(clean_stale_shm(since=since, shm_dir=tmp_path)) == [
        "fastrtps_abc",
        "fastrtps_port7002",
    ]
    assert list(tmp_path.iterdir()) == []


def test_participant_ports_follow_the_rtps_mapping() -> None:
    # RTPS 9.6.1.1: 7400 + 250 d + 10 (+ 1 for user data) + 2 id; the files of
    # a domain-77 run were fastrtps_port26661..26671 for ids 0..5.
    assert participant_ports(77, 0) == (26660, 26661)
    assert participant_ports(77, 5) == (26670, 26671)
    assert participant_ports(0, 31) == (7472, 7473)
    # The highest domain of a run (232) with the highest restart id stays a port.
    assert max(participant_ports(232, max(RESTART_PARTICIPANT_IDS))) < 65536


def test_a_restarted_node_gets_no_id_the_run_gave_or_a_live_one_holds(tmp_path: Path) -> None:
    domain = 151
    ids = list(RESTART_PARTICIPANT_IDS)
    first = free_participant_id(domain, taken=set(), shm_dir=tmp_path)
    assert first == ids[0]
    # Taken before in this run: the next one.
    assert free_participant_id(domain, taken={ids[0]}, shm_dir=tmp_path) == ids[1]
    # A live participant's receive segment exists: skipped.
    (tmp_path / f"fastrtps_port{participant_ports(domain, ids[0])[1]}").write_bytes(b"x")
    assert free_participant_id(domain, taken=set(), shm_dir=tmp_path) == ids[1]
    # A process has the discovery port bound: skipped.
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as sock:
        sock.bind(("127.0.0.1", participant_ports(domain, ids[1])[0]))
        assert free_participant_id(domain, taken=set(), shm_dir=tmp_path) == ids[2]
    with pytest.raises(RuntimeError, match="no free Fast DDS participant id"):
        free_participant_id(domain, taken=set(ids), shm_dir=tmp_path)


def test_the_restart_profile_is_the_run_profile_with_the_id(tmp_path: Path) -> None:
    env = discovery_settings(tmp_path)
    out = with_participant_id(env, 29, tmp_path / "restart.xml")
    assert out["FASTRTPS_DEFAULT_PROFILES_FILE"] == str(tmp_path / "restart.xml")
    ns = {"f": "http://www.eprosima.com/XMLSchemas/fastRTPS_Profiles"}
    new = ElementTree.parse(tmp_path / "restart.xml").getroot()
    old = ElementTree.parse(env["FASTRTPS_DEFAULT_PROFILES_FILE"]).getroot()
    rtps = new.find("f:participant/f:rtps", ns)
    assert rtps is not None and rtps.findtext("f:participantID", namespaces=ns) == "29"
    # Everything else is the run's profile.
    rtps.remove(rtps.find("f:participantID", ns))
    assert ElementTree.tostring(new) == ElementTree.tostring(old)
    assert {k: v for k, v in out.items() if k != "FASTRTPS_DEFAULT_PROFILES_FILE"} == {
        k: v for k, v in env.items() if k != "FASTRTPS_DEFAULT_PROFILES_FILE"
    }


def test_the_realtime_profile_is_the_run_profile_with_announcements_every_second(
    tmp_path: Path,
) -> None:
    """Each announcement reaches every participant of the run: in realtime every second."""
    lockstep = discovery_settings(tmp_path)
    realtime = discovery_settings(tmp_path / "logs", realtime=True)
    assert realtime["FASTRTPS_DEFAULT_PROFILES_FILE"] == str(
        tmp_path / "logs" / "fastdds_realtime.xml"
    )
    ns = {"f": "http://www.eprosima.com/XMLSchemas/fastRTPS_Profiles"}
    path = "f:participant/f:rtps/f:builtin/f:discovery_config/f:leaseAnnouncement"
    new = ElementTree.parse(realtime["FASTRTPS_DEFAULT_PROFILES_FILE"]).getroot()
    old = ElementTree.parse(lockstep["FASTRTPS_DEFAULT_PROFILES_FILE"]).getroot()
    for root, expected in ((old, 0.1), (new, REALTIME_ANNOUNCEMENT_S)):
        period = root.find(path, ns)
        assert period is not None
        seconds = int(period.findtext("f:sec", namespaces=ns) or "")
        nanoseconds = int(period.findtext("f:nanosec", namespaces=ns) or "")
        assert seconds + nanoseconds * 1e-9 == pytest.approx(expected)
    # Everything else is the run's profile.
    for root in (new, old):
        parent = root.find(path.rsplit("/", 1)[0], ns)
        assert parent is not None
        parent.remove(parent.find("f:leaseAnnouncement", ns))
    assert ElementTree.tostring(new) == ElementTree.tostring(old)
    (tmp_path / "bad.xml").write_text("<profiles/>")
    with pytest.raises(RuntimeError, match="expected one <leaseAnnouncement> element"):
        realtime_profile(tmp_path / "bad.xml", tmp_path / "out.xml")
