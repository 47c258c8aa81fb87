"""The backend registry (lenticalib.core.plugins): a backend that cannot run here is refused when it is
asked for, in one line naming the ones that can; backends are imported and asked only when named.
Every registry of the package (encoders, renderers, transports, capture cameras, camera models,
avatar drivers) is one Registry: its built-ins load by name, and a third-party distribution's entry
points (a real ``.dist-info`` folder on sys.path, found by importlib.metadata) add backends to
each, a plug-in transport's devices included in ``lenticalib device list``."""

import os
import subprocess
import sys

import cv2
import numpy as np
import pytest

from lenticalib.calib.capture.cameras import CAMERA_KINDS, make_camera, open_camera
from lenticalib.core.errors import BackendUnavailableError, DeviceNotFoundError, InputError
from lenticalib.core.plugins import Registry, load, runnable
from lenticalib.device.discovery import list_devices
from lenticalib.device.transports import TRANSPORTS, open_transport
from lenticalib.render.cameras.models import CAMERA_MODELS, make_cameras
from lenticalib.render.avatar.drivers import DRIVERS, load_driver
from lenticalib.render.encoders import ENCODERS, available_encoders, get_encoder
from lenticalib.render.renderers import RENDERERS, get_renderer, render

from . import backend_plugins

REPO = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
REGISTRIES = {"encoders": ENCODERS, "renderers": RENDERERS, "transports": TRANSPORTS, "cameras": CAMERA_KINDS,
              "camera models": CAMERA_MODELS, "drivers": DRIVERS}
ENTRY_POINTS = """\
[lenticalib.encoders]
firstview = tests.backend_plugins:encode_first_view
fast = tests.backend_plugins:runs_anywhere

[lenticalib.renderers]
grey = tests.backend_plugins:render_grey

[lenticalib.transports]
pigeon = tests.backend_plugins:PigeonTransport
stuckpigeon = tests.backend_plugins:FailingListTransport
lostpigeon = tests.no_such_module:PigeonTransport

[lenticalib.capture_cameras]
pinhole = tests.backend_plugins:PinholeCamera

[lenticalib.camera_models]
orbit = tests.backend_plugins:orbit_cameras

[lenticalib.avatar_drivers]
stillhead = tests.avatar_driver_plugin:drive
"""


@pytest.fixture
def plugin_site(tmp_path, monkeypatch):
    """A folder on sys.path holding an installed distribution whose entry points add one backend to
    every registry (and two broken transports)."""
    site = tmp_path / "site"
    info = site / "lenticalib_test_plugins-1.0.dist-info"
    info.mkdir(parents=True)
    (info / "METADATA").write_text("Metadata-Version: 2.1\nName: lenticalib-test-plugins\nVersion: 1.0\n")
    (info / "entry_points.txt").write_text(ENTRY_POINTS)
    monkeypatch.syspath_prepend(str(site))
    return site

ENTRIES = {"anywhere": "tests.backend_plugins:runs_anywhere", "hardware": "tests.backend_plugins:needs_hardware",
           "missing": "tests.no_such_module:render"}


def test_a_backend_that_cannot_run_here_is_refused_in_one_line_naming_those_that_can():
    with pytest.raises(BackendUnavailableError) as err:
        load(ENTRIES, "hardware", "renderer", "--renderer", device="cuda")
    assert str(err.value) == ("--renderer: renderer 'hardware' cannot run here: it needs a frobnicator and none is "
                              "attached (renderers that can run here: anywhere)")
    assert backend_plugins.ASKED[-1] == "cuda"


def test_a_backend_that_can_run_here_is_handed_out():
    assert load(ENTRIES, "hardware", "renderer", "--renderer", device="frob:0")() == "ran on the hardware"
    assert load(ENTRIES, "anywhere", "renderer", "--renderer")() == "ran"
    assert runnable(ENTRIES, "frob:0") == ["anywhere", "hardware"]  # one whose module is missing is left out
    with pytest.raises(InputError, match="unknown renderer 'nope'"):
        load(ENTRIES, "nope", "renderer", "--renderer")


def test_only_the_backend_asked_for_is_asked():
    backend_plugins.ASKED.clear()
    load(ENTRIES, "anywhere", "renderer", "--renderer", device="cuda")
    assert backend_plugins.ASKED == []


def test_asking_for_the_cpu_backends_imports_no_torch():
    code = ("import sys; from lenticalib.render.renderers import get_renderer; "
            "from lenticalib.render.encoders import get_encoder; "
            "get_renderer('cpu', device='cpu'); get_encoder('fast', device='cpu'); print('torch' in sys.modules)")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert out.returncode == 0 and out.stdout.strip() == "False", out.stderr


def test_the_gsplat_renderer_and_the_torch_encoder_say_whether_they_can_run_here():
    torch = pytest.importorskip("torch")
    from lenticalib.render.encoders import get_encoder
    from lenticalib.render.renderers import get_renderer

    if torch.cuda.is_available():  # the GPU machine: both are handed out for the GPU
        assert get_renderer("gsplat", device="cuda") and get_encoder("torch", device="cuda")
        with pytest.raises(BackendUnavailableError, match="renders on a CUDA device, not on 'cpu'"):
            get_renderer("gsplat", device="cpu")
        return
    with pytest.raises(BackendUnavailableError) as err:
        get_renderer("gsplat")
    assert str(err.value) == ("renderer: renderer 'gsplat' cannot run here: it needs a CUDA GPU and torch sees "
                              "none (renderers that can run here: cpu, gl, gl-compute)")
    with pytest.raises(BackendUnavailableError) as err:
        get_encoder("torch", device="cuda")
    assert "encoder 'torch' cannot run here: device 'cuda' requested but torch sees no CUDA device" in str(err.value)
    assert "(encoders that can run here: fast, gl, reference, tables)" in str(err.value)
    assert get_encoder("torch", device="cpu") and get_encoder("torch")  # on the CPU it runs


# -- every registry on the one loader ------------------------------------------------------------

def test_a_builtin_backend_loads_without_reading_the_entry_points(monkeypatch):
    # encode() asks the registry every frame: the entry-point scan (milliseconds) is for plug-ins
    from lenticalib.core import plugins

    calls = []
    real = plugins.metadata.entry_points
    monkeypatch.setattr(plugins.metadata, "entry_points", lambda **kw: calls.append(kw) or real(**kw))
    assert callable(get_encoder("fast")) and callable(ENCODERS.load("reference", "encoder"))
    assert calls == []
    with pytest.raises(InputError, match="unknown encoder 'nope'"):
        get_encoder("nope")
    assert calls  # a name that is not built in is looked for among the plug-ins


@pytest.mark.parametrize("kind", sorted(REGISTRIES))
def test_every_registry_loads_its_builtins_by_name(kind):
    registry = REGISTRIES[kind]
    assert registry.builtin and set(registry.builtin) <= set(registry)
    for name, target in registry.builtin.items():
        backend = registry[name]  # imported now, by its "module:attribute" string
        assert callable(backend) and f"{backend.__module__}:{backend.__qualname__}" == target
        if kind == "cameras":
            assert backend.kind == name
    if kind == "transports":  # every built-in that finds devices says so itself
        assert all(callable(registry[name].list_devices) for name in ("serial", "hid", "usb", "emu"))


def test_the_simulated_camera_is_a_sim_backend_and_no_backend_loads_with_its_registry():
    assert CAMERA_KINDS["sim"].__module__ == "lenticalib.sim.capture_backend"
    code = ("import sys; from lenticalib.calib.capture.cameras import CAMERA_KINDS, make_camera; "
            "from lenticalib.device.transports import TRANSPORTS; from lenticalib.render.cameras.models import "
            "CAMERA_MODELS; print(list(CAMERA_KINDS), list(TRANSPORTS)); make_camera('manual'); "
            "print(sorted(m for m in sys.modules if m.startswith(('lenticalib.sim', 'lenticalib.calib.capture.cameras.', "
            "'lenticalib.device.transports.'))))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120, cwd=REPO)
    assert out.returncode == 0, out.stderr
    names, modules = out.stdout.strip().splitlines()
    assert names == "['gphoto2', 'opencv', 'manual', 'sim'] ['serial', 'socket', 'hid', 'usb', 'emu']"
    assert modules == ("['lenticalib.calib.capture.cameras.base', 'lenticalib.calib.capture.cameras.files', "
                       "'lenticalib.calib.capture.cameras.manual', 'lenticalib.device.transports.base']")


def test_entry_points_add_a_backend_to_every_registry(plugin_site, tmp_path):
    assert "firstview" in available_encoders() and get_encoder("firstview") is backend_plugins.encode_first_view
    assert get_encoder("fast").__module__ == "lenticalib.render.encoders.fast"  # a built-in is not taken over
    assert get_renderer("grey") is backend_plugins.render_grey
    views = render(None, np.zeros((3, 4, 4)), np.zeros((3, 3, 3)), 5, 2, renderer="grey")
    assert views.shape == (3, 2, 5, 4) and float(views.min()) == 0.5
    with open_transport("pigeon://loft-7") as pipe:
        assert isinstance(pipe, backend_plugins.PigeonTransport) and pipe.is_open
        pipe.write(b"coo")
        assert pipe.read(8, 0.1) == b"coo"
    camera = make_camera("pinhole:front", aperture=2.8)
    assert isinstance(camera, backend_plugins.PinholeCamera) and camera.spec == "pinhole:front"
    with open_camera("pinhole", aperture=2.8) as camera:
        raster = np.arange(2 * 3 * 3, dtype=np.uint8).reshape(2, 3, 3)
        photo = camera.capture("white", raster, tmp_path / "captures" / "white")
    assert photo.name == "white.png" and np.array_equal(cv2.imread(str(photo)), raster)
    with pytest.raises(InputError, match=r"choose one of gphoto2, manual, opencv, pinhole, sim"):
        make_camera("canon")
    cameras = make_cameras("orbit", (np.zeros(3), np.ones(3)), 4)
    assert cameras.params["Y"] == 10.0 and cameras.params["N"] == 4
    assert load_driver("stillhead").control_dim == 4
    with pytest.raises(InputError, match=r"use module:callable or one of rig, stillhead"):
        load_driver("nohead")


def test_a_plugin_that_does_not_import_is_refused_in_one_line(plugin_site):
    with pytest.raises(BackendUnavailableError) as err:
        open_transport("lostpigeon://loft")
    assert str(err.value) == ("lostpigeon://loft: transport 'lostpigeon' is not available: no module named "
                              "'tests.no_such_module' (install its dependencies)")
    with pytest.raises(DeviceNotFoundError, match=r"unknown transport 'owl' \(use one of: emu, hid, lostpigeon, "):
        open_transport("owl://tree")
    broken = Registry("encoder", {"flame": "tests.avatar_driver_broken:drive"}, None)
    with pytest.raises(BackendUnavailableError) as err:
        broken.load("flame", "--encoder")
    assert str(err.value) == ("--encoder: encoder 'flame' failed to import: RuntimeError: the FLAME model file is "
                              "missing")


def test_a_transport_whose_library_is_missing_names_it(monkeypatch):
    monkeypatch.setitem(sys.modules, "serial", None)  # import serial fails as if pyserial were not installed
    monkeypatch.delitem(sys.modules, "lenticalib.device.transports.serial", raising=False)
    with pytest.raises(BackendUnavailableError) as err:
        open_transport("serial:///dev/ttyACM9")
    assert str(err.value) == ("serial:///dev/ttyACM9: transport 'serial' is not available: no module named 'serial' "
                              "(install pyserial (pip install pyserial))")
    _, notes = list_devices(emulators=False)
    assert notes[0] == ("serial devices not searched: transport 'serial' is not available: no module named "
                        "'serial' (install pyserial (pip install pyserial))")


def test_device_list_shows_plugin_transports(plugin_site, tmp_path):
    emulators = tmp_path / "emulators"
    emulators.mkdir()
    (emulators / "bench.flash").write_bytes(b"")
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(plugin_site), REPO, os.environ.get("PYTHONPATH", "")]),
           "LENTICALIB_EMULATOR_DIR": str(emulators), "XDG_RUNTIME_DIR": str(tmp_path / "run")}
    out = subprocess.run([sys.executable, "-m", "lenticalib.cli", "device", "list"], capture_output=True, text=True,
                         cwd=REPO, env=env, timeout=120)
    assert out.returncode == 0, out.stderr
    lines = out.stdout.splitlines()
    bench = lines.index(f"{'emu://bench':<40} lc32   in-process emulator ({emulators / 'bench.flash'})")
    assert lines[bench + 1] == f"{'pigeon://loft-7':<40} lc32   carrier pigeon loft  serial P7"
    assert "note: one bird is out" in lines
    assert ("note: lostpigeon devices not searched: transport 'lostpigeon' is not available: no module "
            "named 'tests.no_such_module' (install its dependencies)") in lines
    assert "note: stuckpigeon devices not searched: listing them failed: OSError: the loft door is stuck" in lines


def test_an_unknown_camera_model_is_refused_before_the_avatar_is_read(tmp_path):
    out = subprocess.run([sys.executable, "-m", "lenticalib.cli", "render", str(tmp_path / "missing.ply"), "--profile",
                          str(tmp_path / "missing.json"), "--camera-model", "fisheye", "-o", str(tmp_path / "frames")],
                         capture_output=True, text=True, cwd=REPO, timeout=120)
    assert out.returncode == 2 and out.stderr.splitlines() == [
        "lenticalib: error: --camera-model: unknown camera model 'fisheye' (use one of arc, shear)"], out.stderr
    assert not (tmp_path / "frames").exists()
