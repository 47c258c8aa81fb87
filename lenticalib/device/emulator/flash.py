"""The emulated controller's flash memory, kept in an image file that survives restarts.

Image layout (``drivers/protocol-v1.md`` section 5), 768 bytes:

    0x000  factory block (256 B): magic b"LTFI", u16 version, model[32], serial[16],
           firmware_version[16], CRC-32; written once when the image is created, never by
           the firmware
    0x100  slot 0 (256 B): record (128 B), commit word u32 at +128, rest erased
    0x200  slot 1 (256 B): the same

NOR semantics: erase sets a whole slot to 0xFF, program can only clear bits (new = old AND
data).  Every erase and program is one *operation*; each is written to the file before the
next begins (``os.pwrite``; a killed process keeps what it wrote, as a power cut keeps what
reached the flash cells).  ``power_cut_after=K`` ends the K-th operation with a
:class:`PowerCut` (``torn=True``: only the first half of that operation reaches the flash).
The firmware has no way to touch the factory block: :meth:`erase_slot` and :meth:`program`
take slot-relative addresses and refuse anything outside a slot.
"""

from __future__ import annotations

import fcntl
import os
import struct
import tempfile
import zlib
from pathlib import Path

from ...core.files.atomic import current_umask
from ...core.errors import DeviceError, InputError

FACTORY_MAGIC = b"LTFI"
FACTORY_VERSION = 1
FACTORY_SIZE = 256
SLOT_SIZE = 256
SLOT_COUNT = 2
IMAGE_SIZE = FACTORY_SIZE + SLOT_COUNT * SLOT_SIZE
ERASED = 0xFF
_FACTORY = struct.Struct("<4sH32s16s16s")


class PowerCut(Exception):
    """The emulated power failed after (or during) a flash operation."""


def slot_address(slot: int) -> int:
    return FACTORY_SIZE + slot * SLOT_SIZE


def create_image(path: str | os.PathLike, *, model: str, serial: str, firmware_version: str) -> None:
    """Write a new image (factory block, both slots erased); never replaces an existing file.

    The folder must exist (a missing one is an InputError naming it; nothing is created but the
    file).  ``model`` (<= 32), ``serial`` (<= 16) and ``firmware_version`` (<= 16) are printable ASCII;
    InputError names the one that is not.
    """
    path = Path(path)
    fields = {"serial": (serial, 16), "model": (model, 32), "firmware version": (firmware_version, 16)}
    for name, (text, limit) in fields.items():
        if not (text.isascii() and text.isprintable() and 1 <= len(text) <= limit):
            raise InputError(f"must be 1 to {limit} printable ASCII characters, got {text!r}", source=name)
    factory = _FACTORY.pack(FACTORY_MAGIC, FACTORY_VERSION, model.encode("ascii"), serial.encode("ascii"),
                            firmware_version.encode("ascii"))
    factory += struct.pack("<I", zlib.crc32(factory))
    factory += bytes([ERASED]) * (FACTORY_SIZE - len(factory))
    data = factory + bytes([ERASED]) * (SLOT_COUNT * SLOT_SIZE)
    folder = path.parent if str(path.parent) else Path(".")
    if not folder.is_dir():
        raise InputError("the folder for the flash image does not exist", source=str(folder),
                         hint="create it first, or choose another `image` path")
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=folder)  # a new file: never a link's target
    try:
        os.fchmod(fd, 0o666 & ~current_umask())  # the umask's mode, as every output (mkstemp makes 0600)
        with os.fdopen(fd, "wb") as fh:
            fh.write(data)
            fh.flush()
            os.fsync(fh.fileno())
        try:
            os.link(tmp, path)  # atomic and never clobbers: two emulators creating one image agree
        except FileExistsError:
            pass
    finally:
        os.unlink(tmp)


class FlashImage:
    """An open flash image.  Shapes: slots are ``SLOT_SIZE`` bytes, addresses slot-relative.

    Opening takes an exclusive lock on the file, so two emulators never share one flash.
    ``operations`` counts erases and programs since opening; ``log`` records each as
    ``(kind, absolute_offset, length)`` for tests that check where the firmware wrote.
    """

    def __init__(self, path: str | os.PathLike, *, power_cut_after: int | None = None, torn: bool = False):
        self.path = Path(path)
        try:
            self._fd = os.open(self.path, os.O_RDWR)
        except FileNotFoundError:
            raise InputError("flash image not found", source=str(self.path),
                             hint="start 'lenticalib emulate' once to create it") from None
        except OSError as exc:
            raise InputError(f"cannot open the flash image: {exc.strerror}", source=str(self.path),
                             hint="give `image` a writable file") from None
        try:
            fcntl.flock(self._fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            os.close(self._fd)
            raise DeviceError("flash image is in use by another running emulator", source=str(self.path),
                              hint="stop that emulator or give this one another `image` file") from None
        size = os.fstat(self._fd).st_size
        head = os.pread(self._fd, FACTORY_SIZE, 0)
        if size != IMAGE_SIZE or head[:4] != FACTORY_MAGIC or \
                zlib.crc32(head[:_FACTORY.size]) != struct.unpack_from("<I", head, _FACTORY.size)[0]:
            self.close()
            raise InputError(f"not a lenticalib flash image ({size} bytes, expected {IMAGE_SIZE} "
                             "with a valid factory block)", source=str(self.path),
                             hint="give a new file name to create a fresh image")
        _, _, model, serial, firmware = _FACTORY.unpack_from(head)
        self.model = model.rstrip(b"\0").decode("ascii", "replace")
        self.serial = serial.rstrip(b"\0").decode("ascii", "replace")
        self.firmware_version = firmware.rstrip(b"\0").decode("ascii", "replace")
        self.power_cut_after = power_cut_after
        self.torn = torn
        self.operations = 0
        self.log: list[tuple[str, int, int]] = []
        self.dead = False

    def close(self) -> None:
        if self._fd >= 0:
            os.close(self._fd)  # also releases the lock
            self._fd = -1

    def read_slot(self, slot: int, offset: int = 0, length: int = SLOT_SIZE) -> bytes:
        self._check(slot, offset, length)
        return os.pread(self._fd, length, slot_address(slot) + offset)

    def erase_slot(self, slot: int) -> None:
        self._check(slot, 0, SLOT_SIZE)
        self._operation("erase", slot_address(slot), bytes([ERASED]) * SLOT_SIZE)

    def program(self, slot: int, offset: int, data: bytes) -> None:
        """NOR program: the cells become ``old AND data``."""
        self._check(slot, offset, len(data))
        old = self.read_slot(slot, offset, len(data))
        new = bytes(a & b for a, b in zip(old, data))
        self._operation("program", slot_address(slot) + offset, new)

    def _check(self, slot: int, offset: int, length: int) -> None:
        if self.dead:
            raise PowerCut("flash accessed after the power cut")
        if slot not in range(SLOT_COUNT) or offset < 0 or length < 0 or offset + length > SLOT_SIZE:
            raise ValueError(f"flash access outside the calibration slots: slot {slot}, "
                             f"offset {offset}, length {length}")

    def _operation(self, kind: str, address: int, data: bytes) -> None:
        assert FACTORY_SIZE <= address and address + len(data) <= IMAGE_SIZE
        self.operations += 1
        cut = self.power_cut_after is not None and self.operations >= self.power_cut_after
        if cut and self.torn:
            data = data[:max(1, len(data) // 2)]
        os.pwrite(self._fd, data, address)
        self.log.append((kind, address, len(data)))
        if cut:
            self.dead = True
            self.close()
            raise PowerCut(f"power cut after flash operation {self.operations} ({kind})")
