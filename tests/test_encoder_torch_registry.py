"""The 'torch' encoder's registry entry, with and without PyTorch installed (runs in either case)."""

import sys

import pytest

from lenticalib.core.errors import BackendUnavailableError
from lenticalib.render.encoders import available_encoders, get_encoder


def test_registry_lists_torch():
    assert "torch" in available_encoders()


def test_without_torch_the_registry_says_pip_install_torch(monkeypatch):
    monkeypatch.setitem(sys.modules, "torch", None)  # "import torch" now fails (whether or not it is installed)
    monkeypatch.delitem(sys.modules, "lenticalib.render.encoders.torch_encoder", raising=False)
    with pytest.raises(BackendUnavailableError, match=r"\(pip install torch\)$") as info:
        get_encoder("torch")
    assert "\n" not in str(info.value)
    assert get_encoder("tables")  # the others are untouched
