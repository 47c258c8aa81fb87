"""Transport faults: every injected fault ends in a verified success (after retries) or a clear
DeviceError; never a wrong record reported as good, never a hang."""

from __future__ import annotations

import time

import pytest

from lenticalib.device import PanelController
from lenticalib.core.errors import DeviceDisconnectedError, DeviceError, DeviceTimeoutError

from .device_support import VIAS, emulator_process, no_hang, profile_a, profile_b, same_constants

FAULTS = {
    "drop": "drop=0.3",
    "corrupt": "corrupt=0.3",
    "duplicate": "duplicate=0.5",
    "delay": "delay=0.3&delay-s=0.25",   # longer than the command timeout below: stale replies
    "stale": "stale=0.5",
    "mixed": "drop=0.1&corrupt=0.1&duplicate=0.2&delay=0.1&delay-s=0.25&stale=0.2",
}
TIMEOUT, FLASH_TIMEOUT, RETRIES = 0.15, 0.3, 6
# the longest a flash may take: every request times out on every attempt
BOUND = 12 * (RETRIES + 1) * FLASH_TIMEOUT + 5


@pytest.fixture(autouse=True)
def emulator_dir(tmp_path, monkeypatch):
    monkeypatch.setenv("LENTICALIB_EMULATOR_DIR", str(tmp_path / "emu"))


def open_fast(url: str, retries: int = RETRIES) -> PanelController:
    panel = PanelController.open(url, retries=retries)
    panel.command_timeout, panel.flash_timeout = TIMEOUT, FLASH_TIMEOUT
    return panel


def check_device_holds_old_or_new(name: str, via: str):
    with PanelController.open(f"emu://{name}?via={via}") as panel:
        held = panel.read_record().to_profile()
    assert same_constants(held, profile_a()) or same_constants(held, profile_b())
    return held


@pytest.mark.parametrize("fault", [pytest.param(f, marks=pytest.mark.slow) if f == "drop" else f  # the slowest fault
                                   for f in sorted(FAULTS)])
def test_faulty_link_gives_verified_success_or_clear_error(fault):
    """Six flashes over a faulty link (three transports, two seeds): each ends in a verified
    success or one clean DeviceError line, the panel holds the old or the new record after each
    (the new one after every success), and at least half succeed: retries must absorb the
    faults, not merely fail cleanly."""
    outcomes = []
    for via in VIAS:
        for seed in (1, 2):
            name = f"{fault}-{via}-{seed}"
            with PanelController.open(f"emu://{name}?via={via}") as panel:
                panel.flash(profile_a())
            start = time.monotonic()
            with open_fast(f"emu://{name}?via={via}&{FAULTS[fault]}&seed={seed}") as panel:
                try:
                    result = panel.flash(profile_b())
                except DeviceError as exc:
                    assert str(exc) and "\n" not in str(exc)
                    outcomes.append("error")
                else:
                    assert same_constants(result.record.to_profile(), profile_b())
                    outcomes.append("success")
            assert time.monotonic() - start < BOUND
            held = check_device_holds_old_or_new(name, via)
            if outcomes[-1] == "success":
                assert same_constants(held, profile_b())  # never a wrong record reported as good
    assert outcomes.count("success") >= len(outcomes) // 2, outcomes


@pytest.mark.parametrize("via", VIAS)
def test_moderate_faults_are_absorbed_by_retries(via):
    """With a few lost, corrupt and stale frames the flash succeeds after resends."""
    with open_fast(f"emu://m?via={via}&drop=0.1&corrupt=0.1&stale=0.2&seed=5", retries=8) as panel:
        result = panel.flash(profile_b())
        assert result.retries > 0 and panel.discarded > 0
        assert panel.verify(profile_b()).matches


@pytest.mark.parametrize("via", VIAS)
def test_disconnect_at_every_request_of_a_flash(via):
    with PanelController.open(f"emu://d?via={via}") as panel:
        panel.flash(profile_a())
    for n in range(1, 11):  # a flash is 10 requests: identify, verify, begin, 4 chunks, commit, read, verify
        with open_fast(f"emu://d?via={via}&disconnect-after={n}") as panel:
            with pytest.raises(DeviceError) as info:
                panel.flash(profile_b())
            assert isinstance(info.value, (DeviceDisconnectedError, DeviceTimeoutError))
        check_device_holds_old_or_new("d", via)
    with open_fast(f"emu://d?via={via}&disconnect-after=11") as panel:
        panel.flash(profile_a())  # the 11th request would be the first after a complete flash


def test_silent_device_times_out_with_a_clear_message():
    with open_fast("emu://s?drop=1.0", retries=2) as panel:
        start = time.monotonic()
        with pytest.raises(DeviceTimeoutError, match="no valid reply to IDENTIFY.*3 attempts"):
            panel.identify()
        assert time.monotonic() - start < 3 * TIMEOUT + 1


@pytest.mark.parametrize("via", VIAS)
def test_stale_reply_to_an_earlier_request_is_skipped(via):
    """Every reply follows the controller's earlier reply to the same command (stale=1): same
    CMD, an older SEQ, other contents (the VERIFY and READ_RECORD from before the flash name the
    old record).  The host must skip each by its SEQ and take the reply to its own request: the
    flash succeeds, verified, without a resend."""
    with PanelController.open(f"emu://st?via={via}") as panel:
        panel.flash(profile_a())
    with PanelController.open(f"emu://st?via={via}&stale=1") as panel:
        before = panel.read_record()
        result = panel.flash(profile_b())  # its READ_RECORD and VERIFY each meet the old record's first
        assert result.record.sequence == before.sequence + 1
        assert panel.verify_crc()[1] == result.record.sequence
        assert same_constants(panel.read_record().to_profile(), profile_b())
        assert panel.resends == 0 and panel.discarded >= 10


@pytest.mark.parametrize("via", VIAS)
def test_chatty_device_ends_in_one_timeout_line_within_the_command_timeout(via):
    """A controller that always has bytes ready (``babble``: a HID device with a report always
    pending) never lets the host's input drain; the drain is bounded by the command's timeout,
    so the very first request fails with one DeviceTimeoutError line instead of draining for ever."""
    with open_fast(f"emu://chatty?via={via}&babble=1") as panel, no_hang(30):
        start = time.monotonic()
        with pytest.raises(DeviceTimeoutError, match="keeps sending unasked") as info:
            panel.identify()
        elapsed = time.monotonic() - start
    assert "\n" not in str(info.value) and "emu://chatty" in str(info.value)
    assert elapsed < TIMEOUT + 2.0  # the drain's own bound, not the retries' (which would also end)
    assert panel.resends == 0  # it never got as far as sending


def test_faults_over_tcp_and_pty_processes(tmp_path):
    for transport in ("tcp", "pty"):
        image = tmp_path / f"{transport}.flash"
        with emulator_process("--transport", transport, "--flash", str(image), "--drop", "0.1",
                              "--corrupt", "0.1", "--duplicate", "0.2", "--stale", "0.2", "--seed", "3") as (_, url):
            with open_fast(url, retries=8) as panel:
                panel.flash(profile_b())
                assert panel.verify(profile_b()).matches


def test_disconnect_of_the_pty_process(tmp_path):
    image = tmp_path / "x.flash"
    with emulator_process("--flash", str(image), "--disconnect-after", "4") as (proc, url):
        with open_fast(url) as panel:
            with pytest.raises(DeviceError):
                panel.flash(profile_b())
        assert proc.wait(timeout=10) == 76


def test_a_slow_controller_ends_in_one_timeout_line_within_the_operations_deadline():
    """A controller that asks for one-byte chunks (136 requests a flash) and answers each request
    just before its timeout would take 136 x 0.09 s; the flash as a whole has one deadline,
    ``conversation_s`` (10 x (retries + 1) command timeouts + 2 flash timeouts), and ends in one
    DeviceTimeoutError line within it.  The same controller without the delay flashes fine."""
    from lenticalib.device.client import CONVERSATION_TIMEOUTS

    url = "emu://slow?via=serial&chunk=1"
    with PanelController.open(url) as panel:  # a controller in order, one-byte chunks: flashes whole
        panel.flash(profile_a())
    with PanelController.open(f"{url}&delay=1&delay-s=0.09", retries=1) as panel, no_hang(60):
        panel.command_timeout, panel.flash_timeout = 0.1, 0.2
        limit = panel.conversation_s()
        assert limit == pytest.approx(CONVERSATION_TIMEOUTS * 2 * 0.1 + 2 * 0.2)
        start = time.monotonic()
        with pytest.raises(DeviceTimeoutError, match="flash did not finish within 2.4 s") as info:
            panel.flash(profile_b())
        took = time.monotonic() - start
    assert limit <= took < limit + 0.5, took
    assert "\n" not in str(info.value) and "WRITE_CHUNK" in str(info.value) and url in str(info.value)
    check_device_holds_old_or_new("slow", "serial")
