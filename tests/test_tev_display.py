"""``render --display HOST:PORT``: the image sent to tev as it renders (renderer/display), checked by
a small server that reads tev's IPC protocol as tev's ``src/Ipc.cpp`` does (``IpcPacket::
interpretAsCreateImage`` and ``interpretAsUpdateImage``), and a render that goes on when tev does not."""

import socket
import struct
import threading
import time

import numpy as np
import pytest

from realistic.cli import main
from realistic.core.image_files import read_exr
from realistic.core.validation import display_address
from realistic.errors import UserError
from realistic.renderer.display import TevDisplay

FAST = ["--backend", "numpy", "--res", "150x20", "--spp", "4", "--pass-samples", "300"]


def _cstring(body: bytes, at: int) -> tuple[str, int]:
    end = body.index(b"\0", at)
    return body[at:end].decode("utf-8"), end + 1


def parse_packet(body: bytes) -> dict:
    """One packet's fields (``body``: after the uint32 length), as tev reads them."""
    kind, focus = struct.unpack_from("<b?", body)
    name, at = _cstring(body, 2)
    if kind == 4:  # CreateImage: width, height, channel count, channel names
        width, height, count = struct.unpack_from("<iii", body, at)
        at += 12
        channels = []
        for _ in range(count):
            channel, at = _cstring(body, at)
            channels.append(channel)
        assert at == len(body)
        return {"type": "create", "focus": focus, "name": name, "size": (width, height), "channels": channels}
    assert kind == 6, f"packet type {kind}"  # UpdateImage v3
    (count,) = struct.unpack_from("<i", body, at)
    at += 4
    channels = []
    for _ in range(count):
        channel, at = _cstring(body, at)
        channels.append(channel)
    x, y, width, height = struct.unpack_from("<iiii", body, at)
    at += 16
    offsets = struct.unpack_from(f"<{count}q", body, at)
    strides = struct.unpack_from(f"<{count}q", body, at + 8 * count)
    at += 16 * count
    pixels = width * height
    floats = max(offset + (pixels - 1) * stride + 1 for offset, stride in zip(offsets, strides))
    assert len(body) - at == 4 * floats  # exactly the data the offsets and strides address
    data = np.frombuffer(body, "<f4", floats, at)
    planes = [data[offset::stride][:pixels].reshape(height, width) for offset, stride in zip(offsets, strides)]
    return {"type": "update", "focus": focus, "name": name, "channels": channels, "x": x, "y": y,
            "pixels": np.stack(planes, axis=-1)}


class FakeTev:
    """A server on 127.0.0.1 taking one connection: it reads packets until the client hangs up
    (``mode`` "read"), resets the connection at once ("reset"), or never reads ("stall")."""

    def __init__(self, mode: str = "read"):
        self.server = socket.create_server(("127.0.0.1", 0))
        self.port = self.server.getsockname()[1]
        self.mode, self.packets, self.stop = mode, [], threading.Event()
        self.thread = threading.Thread(target=self._serve, daemon=True)
        self.thread.start()

    def _serve(self) -> None:
        connection, _ = self.server.accept()
        with connection:
            if self.mode == "reset":
                connection.setsockopt(socket.SOL_SOCKET, socket.SO_LINGER, struct.pack("ii", 1, 0))
                return
            if self.mode == "stall":
                self.stop.wait(30)
                return
            stream = connection.makefile("rb")
            while header := stream.read(4):
                (length,) = struct.unpack("<I", header)
                self.packets.append(parse_packet(stream.read(length - 4)))

    def close(self) -> None:
        self.stop.set()
        self.thread.join(30)
        self.server.close()


def applied(packets: list[dict], size: tuple[int, int]) -> np.ndarray:
    """The image tev holds after the update packets, in order."""
    width, height = size
    image = np.full((height, width, 3), np.nan, np.float32)
    for packet in packets:
        tile = packet["pixels"]
        assert tile.shape[0] <= 128 and tile.shape[1] <= 128  # tiles as tev's ipc.py sends them
        assert packet["x"] + tile.shape[1] <= width and packet["y"] + tile.shape[0] <= height
        image[packet["y"]:packet["y"] + tile.shape[0], packet["x"]:packet["x"] + tile.shape[1]] = tile
    return image


CROPPED_AND_EXPOSED = ["--cropwindow", "0.1", "0.9", "0.25", "1", "--shutter", "1/30", "--iso", "800"]


@pytest.mark.parametrize("extra", [[], CROPPED_AND_EXPOSED])
def test_tev_gets_an_rgb_image_named_after_the_output_and_ends_with_the_exr(tmp_path, extra, capsys):
    tev = FakeTev()
    out = tmp_path / "shown.exr"
    assert main(["render", *FAST, *extra, "-o", str(out), "--display", f"127.0.0.1:{tev.port}"]) == 0
    tev.close()
    exr = read_exr(out)[0]
    create, *updates = tev.packets
    assert create == {"type": "create", "focus": True, "name": str(out), "size": (exr.shape[1], exr.shape[0]),
                      "channels": ["R", "G", "B"]}
    assert updates and all(p["type"] == "update" and p["name"] == str(out) and p["channels"] == ["R", "G", "B"]
                           for p in updates)
    assert np.array_equal(applied(updates, create["size"]), exr)  # the last values sent are the EXR's, bit for bit
    assert "warning" not in capsys.readouterr().err


def test_updates_arrive_as_the_render_goes(tmp_path, capsys):
    """More than the final image: a pass's image is sent while later passes run."""
    tev = FakeTev()
    out = tmp_path / "p.exr"
    args = ["--backend", "numpy", "--res", "40x30", "--spp", "16", "--pass-samples", "200", "--threads", "1"]
    assert main(["render", *args, "-o", str(out), "--display", f"127.0.0.1:{tev.port}"]) == 0
    tev.close()
    images = len(tev.packets) - 1  # a 40x30 image is one tile
    assert images >= 2


@pytest.mark.parametrize("mode", ["reset", "nothing listening"])
def test_a_display_that_is_gone_is_one_warning_and_the_render_goes_on(tmp_path, mode, capsys):
    if mode == "reset":
        tev = FakeTev("reset")
        port = tev.port
    else:
        with socket.create_server(("127.0.0.1", 0)) as taken:
            port = taken.getsockname()[1]  # closed again: nothing listens there
    out = tmp_path / "gone.exr"
    assert main(["render", *FAST, "-o", str(out), "--display", f"127.0.0.1:{port}", "--quiet"]) == 0
    err = capsys.readouterr().err
    lines = err.strip().splitlines()
    assert len(lines) == 1 and f"--display 127.0.0.1:{port}" in lines[0] and "rendering on without it" in lines[0]
    assert read_exr(out)[0].shape == (20, 150, 3)
    if mode == "reset":
        tev.close()


def test_a_display_that_stops_reading_never_holds_the_render():
    tev = FakeTev("stall")
    warnings = []
    display = TevDisplay("127.0.0.1", tev.port, "big", 2048, 2048, warnings.append)
    image = np.ones((2048, 2048, 3), np.float32)  # 48 MiB: far beyond what the sockets buffer
    start = time.monotonic()
    for _ in range(20):
        display.show(image)
    assert time.monotonic() - start < 0.5
    display.close(wait_seconds=0.5)
    assert time.monotonic() - start < 3
    assert len(warnings) == 1 and "left behind" in warnings[0]
    tev.close()


@pytest.mark.parametrize("text", ["localhost", "host:0", "host:65536", ":14158", "host:port", "a b:1", "h:+1"])
def test_a_bad_address_is_one_line(text, capsys):
    with pytest.raises(UserError, match="is not HOST:PORT"):
        display_address(text)
    assert main(["render", *FAST, "--display", text]) == 2
    assert len(capsys.readouterr().err.strip().splitlines()) == 1


def test_addresses_as_tev_takes_them():
    assert display_address("127.0.0.1:14158") == ("127.0.0.1", 14158)
    assert display_address("[::1]:14158") == ("::1", 14158)
    assert display_address("render-box.local:1") == ("render-box.local", 1)


def test_a_sequence_shows_each_frame_and_ends_with_the_last(tmp_path, capsys):
    tev = FakeTev()
    out = tmp_path / "seq.exr"
    assert main(["render", *FAST, "--sweep", "fstop=4:8:2", "-o", str(out), "--display", f"127.0.0.1:{tev.port}"]) == 0
    tev.close()
    create, *updates = tev.packets
    assert create["name"] == str(out) and create["size"] == (150, 20)
    assert np.array_equal(applied(updates, create["size"]), read_exr(tmp_path / "seq_0002.exr")[0])
