"""Third-party backends for the registry tests (tests/test_plugins.py): one runs anywhere, one
only where its (made-up) hardware is, which it says through ``unavailable(device)``; and one
backend for each registry of the package (encoder, renderer, transport, capture camera, camera
model), registered through a real distribution's entry points that the tests write."""

import cv2
import numpy as np

from lenticalib.calib.capture.cameras.base import CaptureCamera
from lenticalib.calib.capture.cameras.files import write_photo
from lenticalib.device.transports.base import FoundDevice, Transport
from lenticalib.render.cameras.models import arc_cameras


def runs_anywhere(*args, **kwargs):
    return "ran"


def needs_hardware(*args, **kwargs):
    return "ran on the hardware"


ASKED = []  # the devices needs_hardware.unavailable was asked about


def _unavailable(device=None):
    ASKED.append(device)
    return None if device == "frob:0" else "it needs a frobnicator and none is attached"


needs_hardware.unavailable = _unavailable


def encode_first_view(views, profile):
    """An encoder that shows view 0 (the registry hands views (N, H, W, 3) and a profile)."""
    return views[0].copy()


def render_grey(gaussians, viewmats, Ks, width, height, *, background=None):
    """A renderer that paints every view 50 % grey, opaque: (N, H, W, 4) float32."""
    return np.full((len(viewmats), height, width, 4), 0.5, np.float32)


class PigeonTransport(Transport):
    """``pigeon://LOFT``: a loopback byte pipe that lists one loft among the devices."""

    kind = "pigeon"

    @classmethod
    def list_devices(cls):
        return [FoundDevice("pigeon://loft-7", "pigeon", "lc32", "carrier pigeon loft", "P7")], ["one bird is out"]

    def _open(self) -> None:
        self.buffer = bytearray()

    def _close(self) -> None:
        pass

    def _write(self, data: bytes) -> None:
        self.buffer += data

    def _read(self, max_bytes: int, timeout: float) -> bytes:
        out, self.buffer = bytes(self.buffer[:max_bytes]), self.buffer[max_bytes:]
        return out


class FailingListTransport(PigeonTransport):
    """A transport whose listing breaks: device list notes it and lists the rest."""

    @classmethod
    def list_devices(cls):
        raise OSError("the loft door is stuck")


class PinholeCamera(CaptureCamera):
    """``pinhole[:NAME]``: a capture camera kind whose photo is the shown raster itself (PNG)."""

    kind = "pinhole"
    OPTIONS = ("aperture",)

    def _open(self) -> list[str]:
        return [f"pinhole camera, aperture {self.options.get('aperture', 'open')}"]

    def _capture(self, name, shown, destination):
        ok, data = cv2.imencode(".png", np.ascontiguousarray(shown))
        assert ok
        return write_photo(data.tobytes(), destination, ".png")


def orbit_cameras(bbox_min, bbox_max, n_views=32, **options):
    """A camera model: the arc with a fixed 10 degree yaw range."""
    return arc_cameras(bbox_min, bbox_max, n_views, **{**options, "yaw_range_deg": 10.0})
