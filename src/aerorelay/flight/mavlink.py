"""MAVLink as PX4 speaks it: version 2 with the common message set (ODOMETRY and every message id
above 255 need version 2). pymavlink picks its wire protocol from the ``MAVLINK20`` environment
variable when a dialect is set: importing this module sets it (unless the process set it already)
and selects the common dialect for every connection pymavlink makes in this process."""

from __future__ import annotations

import os
import select
import socket
from collections.abc import Iterator

from pymavlink import mavutil

os.environ.setdefault("MAVLINK20", "1")
mavutil.set_dialect("common")
MAV = mavutil.mavlink


NETWORK_KINDS = ("udpin", "udpout", "udp", "udpbcast", "tcp", "tcpin")  # udp = udpin in pymavlink
LISTENING_KINDS = {"udpin": socket.SOCK_DGRAM, "udp": socket.SOCK_DGRAM, "tcpin": socket.SOCK_STREAM}
URL_FORMS = "udpin:HOST:PORT, udpout:HOST:PORT, tcp:HOST:PORT, tcpin:HOST:PORT or a serial device path[,BAUD]"


class MavlinkUrlError(ValueError):
    """A MAVLink URL that is malformed, names a missing device, or would listen on a port in use."""


def check_url(url: str, what: str = "MAVLink URL") -> None:
    """A named error (``MavlinkUrlError``, naming ``what``) for a URL pymavlink cannot open as meant: a
    network URL without a host and a port in 1-65535, a serial device that does not exist, a port to
    listen on that another process holds (pymavlink binds with SO_REUSEADDR, so a second listener
    would share it silently)."""
    url = str(url)
    kind, sep, rest = url.partition(":")
    if sep and kind in NETWORK_KINDS:
        host, sep2, port_text = rest.rpartition(":")
        try:
            port = int(port_text)
        except ValueError:
            port = -1
        if not sep2 or not host or not 1 <= port <= 65535:
            raise MavlinkUrlError(f"{what} {url!r}: need {kind}:HOST:PORT with a port in 1-65535")
        if kind in LISTENING_KINDS:
            with socket.socket(socket.AF_INET, LISTENING_KINDS[kind]) as s:
                try:
                    s.bind((host, port))
                except socket.gaierror:
                    raise MavlinkUrlError(f"{what} {url!r}: unknown host {host!r}") from None
                except OSError as exc:
                    raise MavlinkUrlError(f"{what} {url!r}: cannot listen on {host}:{port} ({exc.strerror}; "
                                          "another vehicle or bridge may hold it: choose a free port)") from None
        return
    device = url.split(",", 1)[0]
    if not device or not os.path.exists(device) or os.path.isdir(device):
        raise MavlinkUrlError(f"{what} {url!r}: not a MAVLink URL ({URL_FORMS}) nor an existing serial device")


def connect(url: str, *, system: int, component: int):
    """A MAVLink 2 connection on ``url`` (pymavlink's URL forms: ``udpin:HOST:PORT``, ``udpout:HOST:PORT``,
    ``tcp:HOST:PORT``, a serial device) sending as ``system`` / ``component``; ``check_url`` first."""
    check_url(url)
    try:
        return mavutil.mavlink_connection(url, source_system=system, source_component=component, dialect="common")
    except OSError as exc:  # a closed TCP port, a serial device that refuses, an address not here: named, no traceback
        raise MavlinkUrlError(f"{url!r}: cannot connect ({exc.strerror or exc}): is the autopilot (or SITL) listening "
                              "there?") from None


MAX_MESSAGES_PER_READ = 10_000  # a flood cannot keep a control period reading forever


def drain(link, kind: str | None = None) -> Iterator:
    """Every message waiting on ``link`` now (of type ``kind``, when given; never BAD_DATA), at most
    ``MAX_MESSAGES_PER_READ`` reads a call. On UDP each datagram is parsed on its own: a datagram holds
    whole messages, so garbage or a torn packet cannot swallow the bytes of the datagrams after it
    (pymavlink's parser keeps one buffer across datagrams: random datagrams made it lose the vehicle's
    telemetry for periods at a time). On a stream (TCP, serial) reading stops only when the
    descriptor has nothing left (pymavlink's non-blocking ``recv_match`` returns None for bytes that
    held no whole message even while more wait)."""
    if isinstance(link, mavutil.mavudp):
        for _ in range(MAX_MESSAGES_PER_READ):
            data = link.recv()  # one datagram (a listening link learns its sender here)
            if not data:
                return
            parser = link.mav
            parser.buf, parser.buf_index = bytearray(), 0  # nothing of an earlier datagram carries over
            parser.expected_length = mavutil.mavlink.HEADER_LEN_V1 + 2
            for msg in parser.parse_buffer(data) or []:
                if msg.get_type() == "BAD_DATA":
                    continue
                link.post_message(msg)
                if kind is None or msg.get_type() == kind:
                    yield msg
        return
    for _ in range(MAX_MESSAGES_PER_READ):
        msg = link.recv_match(type=kind, blocking=False)
        if msg is not None:
            if msg.get_type() != "BAD_DATA":
                yield msg
            continue
        fd = getattr(link, "fd", None)
        if fd is None or not select.select([fd], [], [], 0)[0]:
            return
