"""The Dask scheduler a run is given with ``--scheduler``: its address, checked before any
connection, and a probe that it is a Dask scheduler that answers.

``scheduler_address`` accepts ``tcp://HOST:PORT`` (or another of Dask's schemes),
``HOST:PORT`` (TCP) or a scheduler file; ``probe_scheduler`` opens a TCP connection and
waits, under a time limit, for the scheduler's handshake, and names what is there instead
when none comes (nothing listening, silence, an HTTP server, another program).
"""

from __future__ import annotations

import json
import socket
import struct
import time
from pathlib import Path

from satsight.errors import SatsightError

#: Seconds allowed to reach the scheduler: its TCP connection and handshake, Dask's connect.
CONNECT_TIMEOUT_S = 10
#: Address schemes Dask's Client connects to.
_SCHEMES = ("tcp", "tls", "inproc", "ucx", "ws", "wss")


def scheduler_address(text: str) -> str:
    """The Dask address in ``--scheduler``: ``tcp://HOST:PORT`` (or another of Dask's
    schemes), ``HOST:PORT`` (TCP), or the path of a scheduler file (the JSON that
    ``dask scheduler --scheduler-file`` writes). A form Dask cannot connect to is refused
    here, in one line."""
    try:
        from distributed.comm.addressing import parse_address, parse_host_port
    except ImportError:
        raise SatsightError(
            "--scheduler needs Dask: pip install 'satsight[dask]' (or dask[distributed])"
        ) from None
    text = text.strip()
    usage = (
        "expected tcp://HOST:PORT, HOST:PORT or a scheduler file (the address "
        "`dask scheduler` prints, e.g. tcp://10.0.0.5:8786)"
    )
    if not text:
        raise SatsightError(f"--scheduler is empty: {usage}")
    if "://" not in text and (text.endswith(".json") or Path(text).is_file()):
        return _scheduler_file_address(Path(text), usage)
    scheme = text.split("://", 1)[0] if "://" in text else "tcp"
    if scheme not in _SCHEMES:
        raise SatsightError(
            f"--scheduler {text}: unknown scheme {scheme}:// (Dask knows "
            f"{', '.join(s + '://' for s in _SCHEMES)}); {usage}"
        )
    try:
        scheme, location = parse_address(text)
        if scheme == "inproc":
            return f"{scheme}://{location}"
        host, port = parse_host_port(location)
    except ValueError:
        raise SatsightError(f"--scheduler {text}: no port number; {usage}") from None
    if not host:
        raise SatsightError(f"--scheduler {text}: no host; {usage}")
    if not 1 <= port <= 65535:
        raise SatsightError(f"--scheduler {text}: port {port} is not in 1..65535; {usage}")
    return f"{scheme}://{location}"


def _scheduler_file_address(path: Path, usage: str) -> str:
    try:
        address = json.loads(path.read_text(encoding="utf-8"))["address"]
    except FileNotFoundError:
        raise SatsightError(f"--scheduler {path}: no such scheduler file; {usage}") from None
    except (OSError, ValueError, KeyError, TypeError) as error:
        raise SatsightError(
            f"--scheduler {path}: not a Dask scheduler file (a JSON object with an "
            f"'address'; {type(error).__name__}: {error})"
        ) from None
    if not isinstance(address, str):
        raise SatsightError(f"--scheduler {path}: its 'address' is not text")
    return scheduler_address(address)


def probe_scheduler(address: str, timeout_s: float = CONNECT_TIMEOUT_S) -> None:
    """Check that a Dask scheduler answers at the TCP ``address`` within ``timeout_s``;
    else one line saying what is there instead (no host, nothing listening, silence, an
    HTTP server, another program).

    A Dask scheduler speaks first: on a new connection it sends its handshake, a Dask
    message (8-byte little-endian length, then frames) before reading the client's.
    Dask's own connect reads that handshake without a time limit, so a server that says
    nothing (an HTTP server waits for a request) would hold the run forever.
    """
    from distributed.comm.addressing import parse_address, parse_host_port

    scheme, location = parse_address(address)
    if scheme != "tcp":
        return  # TLS, WebSocket, UCX: Dask's connect, under its own timeout
    host, port = parse_host_port(location)
    where = f"could not reach the Dask scheduler at {address}"
    try:
        stream = socket.create_connection((host, port), timeout=timeout_s)
    except socket.gaierror:
        raise SatsightError(
            f"{where}: the host name {host} is not known; check --scheduler"
        ) from None
    except ConnectionRefusedError:
        raise SatsightError(
            f"{where}: nothing listens on port {port} of {host} (connection refused); "
            f"start one there (dask scheduler --port {port}) or check --scheduler"
        ) from None
    except TimeoutError:
        raise SatsightError(
            f"{where}: no answer to a connection in {timeout_s:g} s (the host is down or "
            "a firewall drops the port)"
        ) from None
    except OSError as error:
        raise SatsightError(f"{where}: {error.strerror or error}") from None
    with stream:
        first = _receive(stream, 16, timeout_s)
        if first is None:
            found = _http_server(host, port)
            raise SatsightError(
                f"{where}: {found or 'a program'} listens there but sent no Dask "
                f"handshake in {timeout_s:g} s; give the scheduler's own port (8786 unless set; "
                "the dashboard's 8787 is an HTTP server)"
            )
        if len(first) < 16 or not _looks_like_dask(first):
            first += _receive(stream, 48, 0.5) or b""  # the rest of a greeting line
            shown = first.split(b"\r\n", 1)[0][:40].decode("ascii", "replace")
            kind = "an HTTP server" if first.startswith(b"HTTP/") else "a program"
            raise SatsightError(
                f"{where}: {kind} there answered {shown!r}, not a Dask handshake; "
                "check --scheduler (the scheduler's port is 8786 unless set)"
            )


def _receive(stream: socket.socket, size: int, timeout_s: float) -> bytes | None:
    """Up to ``size`` bytes the peer sends within ``timeout_s`` (None: silence)."""
    stream.settimeout(timeout_s)
    data = b""
    deadline = time.monotonic() + timeout_s
    try:
        while len(data) < size and time.monotonic() < deadline:
            stream.settimeout(max(deadline - time.monotonic(), 0.01))
            chunk = stream.recv(size - len(data))
            if not chunk:
                break
            data += chunk
    except TimeoutError:
        pass
    except OSError:
        return data or None
    return data or None


def _looks_like_dask(first: bytes) -> bool:
    """The first 16 bytes of a Dask TCP message: the byte count of what follows, then
    the number of frames, both little-endian uint64 and small for a handshake."""
    total, frames = struct.unpack("<QQ", first[:16])
    return 0 < total < 2**24 and 0 < frames < 2**10


def _http_server(host: str, port: int) -> str | None:
    """'an HTTP server (Server: ...)' when one answers a GET at host:port, else None."""
    try:
        with socket.create_connection((host, port), timeout=3) as stream:
            stream.sendall(f"HEAD / HTTP/1.0\r\nHost: {host}\r\n\r\n".encode("ascii"))
            reply = _receive(stream, 1024, 3.0) or b""
    except OSError:
        return None
    if not reply.startswith(b"HTTP/"):
        return None
    server = [
        line.split(b":", 1)[1].strip().decode("ascii", "replace")
        for line in reply.split(b"\r\n")
        if line.lower().startswith(b"server:")
    ]
    return "an HTTP server" + (f" ({server[0]})" if server else "")
