"""Serve an emulated controller on a pseudo-terminal or a loopback TCP port (``lenticalib emulate``).

The first line written to stdout is the URL a client opens (``serial:///dev/pts/5`` or
``socket://127.0.0.1:40123``); the server then runs until SIGINT/SIGTERM.  Exit status:
0 when stopped, :data:`EXIT_POWER_CUT` after an injected power cut (the flash image keeps
what was written), :data:`EXIT_DISCONNECT` after an injected disconnect.

While it runs, a small JSON file in the runtime directory announces it, so
``lenticalib device list`` shows running emulators.
"""

from __future__ import annotations

import json
import os
import select
import signal
import socket
import stat
import sys
import tempfile
import time
import tty
from pathlib import Path

from ...core.files.atomic import write_text_atomic
from ...core.files.documents import FORMATS, check_envelope, document_text
from ...core.errors import InputError
from .controller import TRANSMIT_BUFFER, EmulatedController, LinkDown

EXIT_POWER_CUT = 75
EXIT_DISCONNECT = 76
ANNOUNCEMENT = FORMATS["lenticalib.emulator-announcement"]  # RUNTIME/<pid>.json of a running emulator


def runtime_dir(*, create: bool = True) -> Path | None:
    """The folder where running emulators announce themselves, private to this user.

    ``$XDG_RUNTIME_DIR/lenticalib/emulators``, else ``TMP/lenticalib-UID/emulators`` (TMP is
    ``$TMPDIR`` or ``/tmp``, where anyone may have created that name first).  Both folders must
    be real folders (not symbolic links) owned by this user and private (mode 0700): they are
    created so, and a folder of ours that an older lenticalib left readable by others is made
    private; anything else is refused with one InputError line.  None when ``create`` is False
    and the folder does not exist.
    """
    xdg = os.environ.get("XDG_RUNTIME_DIR")
    root = Path(xdg) / "lenticalib" if xdg else Path(tempfile.gettempdir()) / f"lenticalib-{os.getuid()}"
    folder = root / "emulators"
    for path in (root, folder):
        if not _private_folder(path, create=create):
            return None
    return folder


def _private_folder(path: Path, *, create: bool) -> bool:
    """Make sure ``path`` is a private folder of ours (see :func:`runtime_dir`); False if absent."""
    if create:
        try:
            os.mkdir(path, 0o700)
        except FileExistsError:
            pass
        except OSError as exc:
            raise InputError(f"cannot create the emulators' runtime folder: {exc.strerror}", source=str(path),
                             hint="set XDG_RUNTIME_DIR to a private folder of yours") from None
    try:
        st = os.lstat(path)
    except FileNotFoundError:
        return False
    if stat.S_ISLNK(st.st_mode):
        problem = "is a symbolic link"
    elif not stat.S_ISDIR(st.st_mode):
        problem = "is not a folder"
    elif st.st_uid != os.getuid():
        problem = f"belongs to another user (uid {st.st_uid})"
    elif st.st_mode & 0o022:
        problem = f"is writable by others (mode {stat.S_IMODE(st.st_mode):o})"
    else:
        problem = None
    if problem:
        raise InputError(f"the emulators' runtime folder {problem}; lenticalib writes only into a private folder "
                         "of its own", source=str(path),
                         hint="remove it if it is not yours, or set XDG_RUNTIME_DIR to a private folder")
    if st.st_mode & 0o077:
        os.chmod(path, 0o700)  # ours and written by us alone (an older lenticalib made it 0755)
    return True


def running_emulators() -> list[dict]:
    """Announcements of emulators whose process is still alive (InputError: the folder is unsafe)."""
    found = []
    folder = runtime_dir(create=False)
    for path in sorted(folder.glob("*.json")) if folder is not None else []:
        try:
            fd = os.open(path, os.O_RDONLY | os.O_NOFOLLOW)
            with os.fdopen(fd, "rb") as fh:
                entry = json.loads(fh.read(65536))
            check_envelope(entry, ANNOUNCEMENT, str(path))
            os.kill(int(entry["pid"]), 0)
        except (OSError, ValueError, KeyError, TypeError):  # InputError is a ValueError
            continue
        found.append(entry)
    return found


class _Announcement:
    def __init__(self, url: str, controller: EmulatedController, transport: str):
        self.path = runtime_dir() / f"{os.getpid()}.json"
        identity = controller.identity
        text = document_text(ANNOUNCEMENT, {"url": url, "pid": os.getpid(), "transport": transport,
                                            "flash": str(controller.flash.path), "serial": identity.serial,
                                            "model": identity.model}, indent=None)
        # a link planted at the name is replaced, never written through
        write_text_atomic(self.path, text, "emulator announcement", follow_links=False)

    def remove(self):
        try:
            self.path.unlink()
        except OSError:
            pass


def _stop_on_signals():
    def stop(signum, frame):
        raise SystemExit(0)

    signal.signal(signal.SIGTERM, stop)
    signal.signal(signal.SIGINT, stop)


def _wait(controller: EmulatedController, fds: list[int]) -> list[int]:
    ready_at = controller.next_ready()
    timeout = 0.5 if ready_at is None else max(0.0, ready_at - time.monotonic())
    return select.select(fds, [], [], timeout)[0]


def _end(reason: str, announcement: _Announcement) -> None:
    """The link died (power cut, disconnect): exit at once, as the hardware would vanish.

    ``os._exit`` closes the pty or socket, which is what the host sees."""
    announcement.remove()
    sys.stdout.flush()
    print(f"lenticalib emulate: {reason}", file=sys.stderr, flush=True)
    os._exit(EXIT_POWER_CUT if reason == "power cut" else EXIT_DISCONNECT)


def serve_pty(controller: EmulatedController) -> None:
    """Serve on a new pseudo-terminal until stopped (never returns normally)."""
    master, slave = os.openpty()
    tty.setraw(slave)  # no echo, no line discipline: the protocol's bytes pass untouched
    os.set_blocking(master, False)
    url = f"serial://{os.ttyname(slave)}"
    announcement = _Announcement(url, controller, "pty")
    _stop_on_signals()
    print(url, flush=True)
    try:
        while True:
            if master in _wait(controller, [master]):
                try:
                    data = os.read(master, 4096)
                except OSError:
                    data = b""
                if data:
                    controller.host_write(data)
            _flush(controller, lambda out: os.write(master, out))
    except LinkDown as exc:
        _end(exc.reason, announcement)
    finally:
        announcement.remove()
        controller.close()


def _flush(controller: EmulatedController, send) -> None:
    """Send the reply bytes that are ready, at most one transmit buffer's worth per call (the
    server loop comes back).  ``send`` is non-blocking: what a host that does not read cannot
    take is dropped, as a device's full transmit buffer drops it; never a wait."""
    sent = 0
    while sent < TRANSMIT_BUFFER:
        out = controller.host_read(4096, 0.0)  # LinkDown propagates to the server loop
        if not out:
            return
        sent += len(out)
        view = memoryview(out)
        while view:
            try:
                n = send(bytes(view))
            except BlockingIOError:
                break
            view = view[n:]


def serve_tcp(controller: EmulatedController, host: str = "127.0.0.1", port: int = 0) -> None:
    """Serve on a TCP port (one client at a time) until stopped."""
    server = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
    server.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
    try:
        server.bind((host, port))
    except OSError as exc:
        server.close()
        controller.close()
        raise InputError(f"cannot listen on {host}:{port}: {exc.strerror}", source="port",
                         hint="choose another port, or 0 for any free one") from None
    server.listen(1)
    url = f"socket://{host}:{server.getsockname()[1]}"
    announcement = _Announcement(url, controller, "tcp")
    _stop_on_signals()
    print(url, flush=True)
    client = None
    try:
        while True:
            fds = [server.fileno()] + ([client.fileno()] if client else [])
            ready = _wait(controller, fds)
            if server.fileno() in ready:
                new, _ = server.accept()
                if client:
                    client.close()  # a new connection replaces the old one, as a re-plugged cable
                controller.reset_link()
                client = new
                client.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
                client.setblocking(False)
            elif client and client.fileno() in ready:
                try:
                    data = client.recv(4096)
                except BlockingIOError:
                    continue
                except OSError:  # reset by the client: like end of stream
                    data = b""
                if not data:
                    client.close()
                    client = None
                    controller.reset_link()
                    continue
                controller.host_write(data)
            if client:
                try:
                    _flush(controller, client.send)
                except OSError:
                    client.close()
                    client = None
    except LinkDown as exc:
        _end(exc.reason, announcement)
    finally:
        announcement.remove()
        controller.close()
