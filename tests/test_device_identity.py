"""Protocol 1.1: the CRC identifies the record, the controller reports its panel, and the host
copes with 1.0 firmware (constant CRC residue, no panel) without ever trusting a constant."""

from __future__ import annotations

import pytest

from lenticalib.device import PanelController
from lenticalib.device.emulator.controller import EmulatedController, ensure_image
from lenticalib.device.emulator.firmware import Firmware
from lenticalib.device.protocol import VERIFY_REPLY, Identity, PanelGeometry, Status
from lenticalib.device.record import LEGACY_CRC_RESIDUE, RECORD_SIZE
from lenticalib.device.controller_families import family_for
from lenticalib.device.transports.base import Transport
from lenticalib.device.url import parse_device_url
from lenticalib.core.errors import DeviceProtocolError, ProfileError

from .device_support import VIAS, profile_a, profile_b, same_constants

HD = dict(width=1920, height=1080)


@pytest.fixture(autouse=True)
def emulator_dir(tmp_path, monkeypatch):
    monkeypatch.setenv("LENTICALIB_EMULATOR_DIR", str(tmp_path / "emu"))


class ConstantCrcFirmware(Firmware):
    """A faulty 1.1 firmware: VERIFY answers the CRC-32 over all 128 bytes (the constant residue),
    as 1.0 did, while claiming protocol 1.1."""

    def _verify(self, payload: bytes):
        status, body = super()._verify(payload)
        if status is Status.OK:
            slot, sequence, _ = VERIFY_REPLY.unpack(body)
            body = VERIFY_REPLY.pack(slot, sequence, LEGACY_CRC_RESIDUE)
        return status, body


class DirectTransport(Transport):
    """The host's byte stream straight into an in-process EmulatedController (for firmware variants
    that no URL selects)."""

    kind = "serial"

    def __init__(self, controller: EmulatedController):
        super().__init__(parse_device_url("emu://direct"), family_for())
        self.controller = controller

    def _open(self):
        pass

    def _close(self):
        self.controller.close()

    def _write(self, data):
        self.controller.host_write(data)

    def _read(self, max_bytes, timeout):
        return self.controller.host_read(max_bytes, timeout)


def test_verify_crc_identifies_the_record():
    with PanelController.open("emu://ident") as panel:
        identity = panel.identify()
        assert identity.version == "1.1" and identity.panel == PanelGeometry(3840, 2160, "RGB", (32,))
        panel.flash(profile_a())
        first = panel.current(identity)
        panel.flash(profile_b())
        second = panel.current(identity)
    assert first.crc_from_device and second.crc_from_device
    assert first.crc != second.crc and LEGACY_CRC_RESIDUE not in (first.crc, second.crc)


def test_a_firmware_answering_a_constant_crc_makes_the_host_fail(tmp_path):
    image = ensure_image(tmp_path / "liar.flash")
    controller = EmulatedController(image)
    controller.firmware = ConstantCrcFirmware(controller.flash, controller.firmware.panel)
    with PanelController(DirectTransport(controller).open()) as panel:
        with pytest.raises(DeviceProtocolError, match="constant every valid record gives") as err:
            panel.flash(profile_a())
        assert "flash verification failed" in str(err.value)
        with pytest.raises(DeviceProtocolError, match="cannot tell records apart"):
            panel.current(panel.identify())


@pytest.mark.parametrize("via", VIAS)
def test_old_firmware_identity_and_crc_fallback(via):
    url = f"emu://old?via={via}&protocol=1.0"
    with PanelController.open(url) as panel:
        identity = panel.identify()
        assert (identity.version, identity.panel) == ("1.0", None)
        warnings = []
        panel.flash(profile_a(), warn=warnings.append)  # blank: nothing to check the panel against
        assert len(warnings) == 1 and "does not report its panel" in warnings[0]
        assert panel.verify_crc()[2] == LEGACY_CRC_RESIDUE  # what 1.0 answers for every record
        first = panel.current(identity)
        result = panel.flash(profile_b(), warn=warnings.append)
        second = panel.current(identity)
    assert len(warnings) == 1 and same_constants(result.record.to_profile(), profile_b())
    assert not first.crc_from_device and first.crc != second.crc  # identified by the bytes read back


def test_old_firmware_refuses_a_profile_for_another_panel_by_its_record():
    with PanelController.open("emu://old-hd?protocol=1.0") as panel:
        panel.flash(profile_a())
        before = panel.verify_crc()
        with pytest.raises(ProfileError, match="profile 1920x1080 pixels, record 3840x2160"):
            panel.flash(profile_a().replace(**HD))
        assert panel.verify_crc() == before


def test_identify_reply_of_10_firmware_decodes_without_a_panel():
    full = Identity(1, 1, 3, 32, RECORD_SIZE, "LC-32", "1.1", "SER", 1, PanelGeometry(1920, 1080, "BGR", (8, 16)))
    old = Identity(1, 1, 3, 32, RECORD_SIZE, "LC-32", "1.0", "SER")
    assert Identity.unpack(full.pack()) == full
    assert Identity.unpack(old.pack()) == old and old.protocol_minor == 0 and old.panel is None
    assert Identity.unpack(full.pack() + b"later minor versions append here") == full
    with pytest.raises(ValueError, match="truncated"):
        Identity.unpack(full.pack()[:-5])


@pytest.mark.parametrize("change,message", [
    (HD, "profile 1920x1080 pixels, panel 3840x2160"),
    ({"subpixel_order": "BGR"}, "profile subpixel order BGR, panel RGB"),
    ({"views": 48}, "profile 48 views, controller supports 32"),
])
def test_a_profile_for_another_panel_is_refused_before_anything_is_written(change, message, tmp_path):
    other = profile_a().replace(**change)
    with PanelController.open("emu://panel") as panel:
        panel.flash(profile_b())
        image = (tmp_path / "emu" / "panel.flash").read_bytes()
        with pytest.raises(ProfileError, match=message) as err:
            panel.flash(other, source="hd.json")
        assert str(err.value).startswith("hd.json: made for another panel than the panel of emu://panel")
        assert "`force`" in str(err.value) and "\n" not in str(err.value)
        assert (tmp_path / "emu" / "panel.flash").read_bytes() == image  # not even the inactive slot erased
        warnings = []
        result = panel.flash(other, force=True, warn=warnings.append)
    assert same_constants(result.record.to_profile(), other)
    assert len(warnings) == 1 and message in warnings[0] and "forced" in warnings[0]


def test_the_emulator_reports_the_panel_it_is_given():
    with PanelController.open("emu://hd?panel=1920x1080&order=BGR&views=8,16") as panel:
        assert panel.identify().panel == PanelGeometry(1920, 1080, "BGR", (8, 16))
        hd = profile_a().replace(views=16, subpixel_order="BGR", **HD)
        assert same_constants(panel.flash(hd).record.to_profile(), hd)
