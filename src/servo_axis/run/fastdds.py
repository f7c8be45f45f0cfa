"""What Fast DDS leaves of a killed node, and participant ids for a restarted one.

With localhost discovery rmw_fastrtps adds the shared-memory transport; a
SIGKILLed participant leaves its segments in ``/dev/shm``
(:func:`clean_stale_shm` removes them), and a node restarted in its place
must not take its participant id (:func:`free_participant_id`,
:func:`with_participant_id`). No rclpy.
"""

from __future__ import annotations

import fcntl
import os
import socket
import time
from collections.abc import Mapping
from pathlib import Path

#: Seconds a lock file nobody holds is taken to be one whose owner has not
#: locked it yet (Fast DDS makes it, then locks it).
LOCK_GRACE_S = 2.0


def _lock_held(path: Path) -> bool:
    """Whether a live process holds the ``flock`` on ``path``."""
    try:
        fd = os.open(path, os.O_RDWR)
    except OSError:
        return False
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except OSError:
        return True
    finally:
        os.close(fd)  # closing releases a lock we took
    return False


def files_in_use(directory: Path, proc: Path = Path("/proc")) -> set[str]:
    """Names of the files in ``directory`` that a live process has open or mapped.

    Read from each process's ``fd`` links and ``maps`` (Linux); a process
    that ends meanwhile, or that this user may not look into, is passed over.
    """
    where = str(directory.resolve())
    prefix = where.rstrip("/") + "/"
    names: set[str] = set()
    for pid in proc.iterdir():
        if not pid.name.isdigit():
            continue
        try:
            with open(pid / "maps", encoding="utf-8", errors="replace") as maps:
                for line in maps:
                    at = line.find(prefix)
                    if at >= 0:
                        names.add(line[at + len(prefix) :].split()[0])
            for fd in (pid / "fd").iterdir():
                target = os.readlink(fd)
                if target.startswith(prefix):
                    names.add(target[len(prefix) :].split()[0])
        except OSError:
            continue
    return names


def clean_stale_shm(
    *, since: float, shm_dir: Path = Path("/dev/shm"), dead_owners_only: bool = False
) -> list[str]:
    """Remove Fast DDS shared-memory files a SIGKILLed node left behind.

    With localhost discovery rmw_fastrtps uses shared memory; a clean exit
    removes its files, SIGKILL does not, and the port segments a killed
    participant had opened stay behind after their last user exits too. A
    segment with an ``_el`` lock file is stale when nobody holds the lock
    (live owners hold it; the kernel releases it when the owner dies) and
    the lock file is older than :data:`LOCK_GRACE_S` (a participant makes
    it, then locks it), whoever still maps the segment; a port segment
    without an ``_el`` when no live process has it or its mutex open or
    mapped (:func:`files_in_use`: a sender's, or one being made).
    Only files touched since ``since`` (epoch seconds: the start of the run)
    are considered, so other users' files are left alone.

    With ``dead_owners_only`` only segments whose lock file exists and is
    free (their owner died) go, which is safe while other participants run:
    a port segment without a lock file may be a sender's about to map it. A
    restarted node gets a participant id of its own
    (:func:`free_participant_id`), so it never opens the dead one's receive
    port; what the dead one left and no live peer still maps is removed here
    all the same, before the restart.
    """
    removed = []
    # A lock file whose segment is gone counts too: Fast DDS may remove a
    # dead owner's port segment when another participant reopens the port,
    # and leave the lock file behind.
    names = {p.name.removesuffix("_el") for p in shm_dir.glob("fastrtps_*")}
    # A port segment without a lock file may be a live sender's, of another
    # run on the machine (a second pytest-xdist worker, a user's): removing
    # it cuts that process off for good (its peers' messages go to a segment
    # nobody reads). Who has it is read from /proc once, if one is looked at,
    # after the listing: a file made in between is open already.
    in_use: set[str] | None = None
    now = time.time()
    for name in sorted(names):
        seg, lock = shm_dir / name, shm_dir / f"{name}_el"
        try:
            touched = max(p.stat().st_mtime for p in (seg, lock) if p.exists())
        except (OSError, ValueError):
            continue
        if touched < since:
            continue
        if lock.exists():
            # A lock file just made may not be locked yet (its owner opens it,
            # then locks it). A dead owner's segment goes even while its peers
            # still map it or look at its lock (nobody writes to it any more).
            try:
                if _lock_held(lock) or now - lock.stat().st_mtime < LOCK_GRACE_S:
                    continue
            except FileNotFoundError:
                continue  # removed meanwhile: its owner closed, or another run cleaned it
        elif dead_owners_only:
            continue
        else:
            in_use = files_in_use(shm_dir) if in_use is None else in_use
            if {name, f"sem.{name}_mutex"} & in_use:
                continue
        for path in (seg, lock, shm_dir / f"sem.{name}_mutex"):
            path.unlink(missing_ok=True)
        removed.append(name)
    return removed


#: The RTPS port mapping (spec 9.6.1.1): base, domain gain, participant gain,
#: and the offsets of a participant's discovery and user-data unicast ports.
RTPS_PORT_BASE, RTPS_DOMAIN_GAIN, RTPS_PARTICIPANT_GAIN = 7400, 250, 2
RTPS_DISCOVERY_OFFSET, RTPS_USER_OFFSET = 10, 11
#: Participant ids a restarted node may take, highest first: within the 32
#: every participant of the profile announces itself to, and above the ids
#: Fast DDS hands out from 0 to the run's own nodes and to outside ones.
RESTART_PARTICIPANT_IDS = range(31, 11, -1)


def participant_ports(domain_id: int, participant_id: int) -> tuple[int, int]:
    """The discovery and user-data unicast ports of ``participant_id`` in ``domain_id``."""
    base = RTPS_PORT_BASE + RTPS_DOMAIN_GAIN * domain_id + RTPS_PARTICIPANT_GAIN * participant_id
    return base + RTPS_DISCOVERY_OFFSET, base + RTPS_USER_OFFSET


def _port_free(port: int) -> bool:
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as sock:
        try:
            sock.bind(("127.0.0.1", port))
        except OSError:
            return False
    return True


def free_participant_id(
    domain_id: int, *, taken: set[int], shm_dir: Path = Path("/dev/shm")
) -> int:
    """A participant id for a restarted node that no participant of the run has had.

    Fast DDS gives a node the lowest free id, i.e. a restarted node the id of
    the one it replaces, and with it the same shared-memory receive port
    (``fastrtps_port<user port>``). The run's other participants keep the
    dead one's segment open under that name and go on writing into it: the
    restarted node matched every topic and received nothing (1 restart in 3
    to 6, seen as a learning unit that never learned again). An id that is
    not in ``taken`` (the ids this run gave before), whose UDP ports are free
    and whose port segment does not exist cannot be one of them.

    Raises
    ------
    RuntimeError
        If none of :data:`RESTART_PARTICIPANT_IDS` is free.
    """
    for pid in RESTART_PARTICIPANT_IDS:
        if pid in taken:
            continue
        ports = participant_ports(domain_id, pid)
        if (shm_dir / f"fastrtps_port{ports[1]}").exists():
            continue
        if all(_port_free(port) for port in ports):
            return pid
    raise RuntimeError(
        f"no free Fast DDS participant id in {RESTART_PARTICIPANT_IDS.stop + 1}.."
        f"{RESTART_PARTICIPANT_IDS.start} for a restarted node in domain {domain_id}"
    )


def with_participant_id(env: Mapping[str, str], participant_id: int, path: Path) -> dict[str, str]:
    """``env`` whose Fast DDS profile (written to ``path``) fixes the participant id."""
    base = Path(env["FASTRTPS_DEFAULT_PROFILES_FILE"]).read_text()
    marker = "<rtps>"
    if base.count(marker) != 1:
        raise RuntimeError(f"{env['FASTRTPS_DEFAULT_PROFILES_FILE']}: expected one {marker}")
    path.write_text(
        base.replace(marker, f"{marker}\n      <participantID>{participant_id}</participantID>")
    )
    return {**env, "FASTRTPS_DEFAULT_PROFILES_FILE": str(path)}


#: Realtime: seconds between a participant's discovery announcements (the
#: shipped profile: 0.1 s, so that a node started late is found at once).
#: Every announcement reaches every participant of the run: the realtime
#: pair's receive threads parsed them on the per-sample path, and the
#: misses came in a 100 ms rhythm. 2 s realtime ptc_friction, alternated
#: run by run (scripts/rt_ab.py, 6 each): a median of 19.5 misses of 2,000
#: with 0.1 s, 7 with 1 s; the bare pair 8.5.
REALTIME_ANNOUNCEMENT_S = 1.0


def realtime_profile(base: Path, path: Path) -> Path:
    """``base``'s Fast DDS profile with announcements every :data:`REALTIME_ANNOUNCEMENT_S`,
    written to ``path`` (its folder made if need be); ``path``."""
    text = base.read_text()
    tag = "leaseAnnouncement"
    start, end = text.find(f"<{tag}>"), text.find(f"</{tag}>")
    if start < 0 or end < 0 or text.count(f"<{tag}>") != 1:
        raise RuntimeError(f"{base}: expected one <{tag}> element")
    seconds = int(REALTIME_ANNOUNCEMENT_S)
    nanoseconds = round((REALTIME_ANNOUNCEMENT_S - seconds) * 1e9)
    period = f"<{tag}><sec>{seconds}</sec><nanosec>{nanoseconds}</nanosec>"
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(text[:start] + period + text[end:])
    return path
