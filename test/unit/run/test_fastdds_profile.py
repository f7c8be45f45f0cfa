"""The Fast DDS profile the runner gives every node (``data/fastdds_localhost.xml``).

Read as Fast DDS reads it (an XML file of ``<profiles>``): the settings the
suite depends on are there, in the profiles marked as default, in the units
Fast DDS takes (``sec`` + ``nanosec``).
"""

from __future__ import annotations

import xml.etree.ElementTree as ET
from importlib import resources

from numpy.testing import assert_allclose

NS = {"f": "http://www.eprosima.com/XMLSchemas/fastRTPS_Profiles"}


def profile() -> ET.Element:
    path = resources.files("servo_axis") / "data" / "fastdds_localhost.xml"
    return ET.fromstring(path.read_text())


def seconds(element: ET.Element | None) -> float:
    assert element is not None
    sec = element.find("f:sec", NS)
    nanosec = element.find("f:nanosec", NS)
    return (
        int(sec.text if sec is not None and sec.text else 0)
        + int(nanosec.text if nanosec is not None and nanosec.text else 0) / 1e9
    )


def default(root: ET.Element, kind: str) -> ET.Element:
    found = [e for e in root.findall(f"f:{kind}", NS) if e.get("is_default_profile") == "true"]
    assert len(found) == 1, f"expected one default <{kind}> profile, got {len(found)}"
    return found[0]


def test_reliable_writers_send_a_heartbeat_every_100_ms() -> None:
    """A lost sample is repaired after the writer's next heartbeat (3 s by default)."""
    writer = default(profile(), "data_writer")
    period = writer.find("f:times/f:heartbeatPeriod", NS)
    assert_allclose(seconds(period), 0.1, rtol=0, atol=1e-12)
    # Only the timing: the QoS a publisher asks for stays rclpy's to set.
    assert writer.find("f:qos", NS) is None
    assert writer.find("f:topic", NS) is None


def test_participants_announce_every_100_ms_with_a_5_s_lease() -> None:
    discovery = default(profile(), "participant").find("f:rtps/f:builtin/f:discovery_config", NS)
    assert discovery is not None
    assert_allclose(seconds(discovery.find("f:leaseAnnouncement", NS)), 0.1, rtol=0, atol=1e-12)
    assert_allclose(seconds(discovery.find("f:leaseDuration", NS)), 5.0, rtol=0, atol=1e-12)
