"""A live view of a render in tev (https://github.com/Tom94/tev), as pbrt-v4's ``--display-server``.

tev listens on TCP (``127.0.0.1:14158`` by default) for its IPC packets: each is a little-endian
uint32 of the packet's whole length (these four bytes included), an int8 packet type, then fields
(bools one byte, int32 and int64 little-endian, strings UTF-8 ending in a NUL byte, pixels float32).
``TevDisplay`` sends CreateImage (type 4: grab focus, name, width, height, channel count, channel
names) once, then UpdateImage version 3 (type 6: grab focus, name, channel count, channel names,
x, y, width, height, an int64 offset and an int64 stride per channel into the float32 data that
follows) in tiles of at most 128 x 128 pixels, as tev's own ``ipc.py`` client does and
``IpcPacket::interpretAsUpdateImage`` in its ``Ipc.cpp`` reads them.

The render never waits for tev: ``show`` hands the newest image to a sender thread (an image not
yet sent is replaced by a newer one), and a display that cannot be reached, stops reading or goes
away is reported once and then left alone.
"""

from __future__ import annotations

import socket
import struct
import threading
from collections.abc import Callable, Iterator

import numpy as np

from realistic.errors import UserError

#: tev's packet types (``IpcPacket::EType`` in its ``Ipc.h``) that the display sends.
CREATE_IMAGE, UPDATE_IMAGE_V3 = 4, 6
#: Pixels per side of an update tile: tev's ``ipc.py`` uses 128 "for typical TCP packets".
TILE = 128
#: Seconds a connection, or a send to a display that stopped reading, may take before it is given up.
SOCKET_TIMEOUT = 5.0
CHANNELS = ("R", "G", "B")


def _text(value: str) -> bytes:
    """A string field: UTF-8 and a NUL byte (a name with a NUL in it is refused)."""
    if "\0" in value:
        raise UserError(f"tev image name {value!r} has a NUL character")
    return value.encode("utf-8") + b"\0"


def _packet(body: bytes) -> bytes:
    return struct.pack("<I", 4 + len(body)) + body


def create_image_packet(name: str, width: int, height: int, grab_focus: bool = True) -> bytes:
    """CreateImage: a blank ``width`` x ``height`` image called ``name`` with channels R, G, B."""
    return _packet(struct.pack("<b?", CREATE_IMAGE, grab_focus) + _text(name)
                   + struct.pack("<iii", width, height, len(CHANNELS)) + b"".join(_text(c) for c in CHANNELS))


def update_image_packets(name: str, image: np.ndarray) -> Iterator[bytes]:
    """UpdateImage (version 3) packets setting every pixel of the (H, W, 3) ``image`` of ``name``,
    tile by tile; the pixels interleaved RGB (channel c at offset c, stride 3)."""
    height, width = image.shape[:2]
    names = b"".join(_text(c) for c in CHANNELS)
    layout = struct.pack("<3q3q", 0, 1, 2, 3, 3, 3)
    for y in range(0, height, TILE):
        for x in range(0, width, TILE):
            tile = np.ascontiguousarray(image[y:y + TILE, x:x + TILE, :3], dtype="<f4")
            yield _packet(struct.pack("<b?", UPDATE_IMAGE_V3, False) + _text(name) + struct.pack("<i", 3) + names
                          + struct.pack("<iiii", x, y, tile.shape[1], tile.shape[0]) + layout + tile.tobytes())


class TevDisplay:
    """Sends a render's images to tev at ``host``:``port`` as image ``name`` (``width`` x ``height``),
    from a thread of its own; ``warn`` is told, once, when the display fails (the render goes on)."""

    def __init__(self, host: str, port: int, name: str, width: int, height: int,
                 warn: Callable[[str], None]) -> None:
        _text(name)
        self.address, self.name, self.size, self.warn = (host, port), name, (width, height), warn
        self._pending: np.ndarray | None = None
        self._closing = False
        self._failed = False
        self._changed = threading.Condition()
        self._thread = threading.Thread(target=self._send_all, name="tev display", daemon=True)
        self._thread.start()

    def show(self, image: np.ndarray) -> None:
        """Send ``image`` (H, W, 3) as soon as the thread can; an image still waiting is dropped."""
        with self._changed:
            if not self._failed:
                self._pending = image
                self._changed.notify()

    def close(self, wait_seconds: float = 2 * SOCKET_TIMEOUT) -> None:
        """Send the image waiting, if any, and hang up; gives up (saying so) after ``wait_seconds``."""
        with self._changed:
            self._closing = True
            self._changed.notify()
        self._thread.join(wait_seconds)
        if self._thread.is_alive():
            self._fail(f"the display took over {wait_seconds:g} s to take the last image: left behind")

    def _fail(self, reason: str) -> None:
        with self._changed:
            first, self._failed, self._pending = not self._failed, True, None
        if first:
            self.warn(f"--display {self.address[0]}:{self.address[1]}: {reason}; rendering on without it")

    def _next(self) -> np.ndarray | None:
        """The next image to send, waiting for one; None once closing with nothing left."""
        with self._changed:
            while self._pending is None and not self._closing:
                self._changed.wait()
            image, self._pending = self._pending, None
            return image

    def _send_all(self) -> None:
        try:
            with socket.create_connection(self.address, timeout=SOCKET_TIMEOUT) as connection:
                connection.sendall(create_image_packet(self.name, *self.size))
                while (image := self._next()) is not None:
                    for packet in update_image_packets(self.name, image):
                        if self._failed:
                            return
                        connection.sendall(packet)
        except OSError as err:
            self._fail(f"cannot send to it ({err.strerror or err})")
