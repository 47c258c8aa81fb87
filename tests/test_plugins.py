"""The backend registry (lenticalib.core.plugins): a backend that cannot run here is refused when it is
asked for, in one line naming the ones that can; backends are imported and asked only when named."""

import subprocess
import sys

import pytest

from lenticalib.core.errors import BackendUnavailableError, InputError
from lenticalib.core.plugins import load, runnable

from . import backend_plugins

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
    assert str(err.value) == ("--renderer: renderer 'gsplat' cannot run here: it needs a CUDA GPU and torch sees "
                              "none (renderers that can run here: cpu)")
    with pytest.raises(BackendUnavailableError) as err:
        get_encoder("torch", device="cuda")
    assert "encoder 'torch' cannot run here: device 'cuda' requested but torch sees no CUDA device" in str(err.value)
    assert "(encoders that can run here: fast, reference, tables)" in str(err.value)
    assert get_encoder("torch", device="cpu") and get_encoder("torch")  # on the CPU it runs
