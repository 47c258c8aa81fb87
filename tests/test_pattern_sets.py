"""Pattern folders (lenticalib.core.pattern_sets): the manifest's ``format`` picks the kind of set, a
third-party kind registers through the ``lenticalib.pattern_sets`` entry-point group, and anything
else is refused in one line naming the manifest."""

from __future__ import annotations

import dataclasses
import json
from importlib import metadata

import numpy as np
import pytest

from lenticalib.calib.patterns.crosstalk_patterns import CrosstalkPatternSet, design_crosstalk_patterns
from lenticalib.calib.patterns.calibration_patterns import PatternSet, design_patterns
from lenticalib.core import plugins
from lenticalib.core.errors import InputError
from lenticalib.core.pattern_sets import MANIFEST_NAME, PATTERN_SET_GROUP, read_pattern_folder, write_patterns
from lenticalib.core.profile import PanelProfile
from lenticalib.core.slides import slides_from_path

STRIPES = "example.stripes"


@dataclasses.dataclass(frozen=True)
class _Stripe:
    name: str
    level: int

    file = property(lambda self: f"{self.name}.png")
    group = property(lambda self: "stripes")


@dataclasses.dataclass(frozen=True)
class StripeSet:
    """A third-party kind: grey levels, one pattern each."""

    width: int
    height: int
    levels: tuple[int, ...]
    views = 2

    @property
    def patterns(self):
        return tuple(_Stripe(f"grey-{v}", v) for v in self.levels)

    names = property(lambda self: [p.name for p in self.patterns])
    set_id = property(lambda self: "-".join(map(str, self.levels)))

    def render(self, pattern):
        return np.full((self.height, self.width, 3), pattern.level, np.uint8)

    def to_dict(self):
        return {"format": STRIPES, "set_id": self.set_id, "width": self.width, "height": self.height,
                "levels": list(self.levels)}


def stripes_from_manifest(data, source):
    if not isinstance(data.get("levels"), list):
        raise InputError("field 'levels' is missing", source=source)
    return StripeSet(data["width"], data["height"], tuple(data["levels"]))


@pytest.fixture
def stripes_registered(monkeypatch):
    """The stripe kind as an installed distribution would register it."""
    real = metadata.entry_points
    ours = metadata.EntryPoint(STRIPES, f"{__name__}:stripes_from_manifest", PATTERN_SET_GROUP)

    def entry_points(**kwargs):
        return [ours] if kwargs.get("group") == PATTERN_SET_GROUP else real(**kwargs)

    monkeypatch.setattr(plugins.metadata, "entry_points", entry_points)


def test_each_built_in_kind_is_read_back_as_written(tmp_path):
    calibration = design_patterns(128, 72, 8)
    crosstalk = design_crosstalk_patterns(PanelProfile(views=8, slant=0.2, period=14.5, offset=3.0, reference_view=4.0,
                                                       width=128, height=72))
    for folder, pattern_set, kind in ((tmp_path / "cal", calibration, PatternSet),
                                      (tmp_path / "xt", crosstalk, CrosstalkPatternSet)):
        write_patterns(folder, pattern_set)
        again = read_pattern_folder(folder)
        assert isinstance(again, kind) and again.set_id == pattern_set.set_id


@pytest.mark.parametrize("manifest", [{"format": "example.stripes", "levels": [0]}, {"format": 3}, [1, 2], {}])
def test_a_manifest_of_no_known_kind_is_refused_in_one_line(tmp_path, manifest):
    (tmp_path / MANIFEST_NAME).write_text(json.dumps(manifest))
    with pytest.raises(InputError) as err:
        read_pattern_folder(tmp_path)
    assert str(err.value) == (f"{tmp_path / MANIFEST_NAME}: is not a lenticalib pattern manifest "
                              "(point at the folder 'lenticalib patterns' wrote)")


def test_a_kind_registered_by_entry_point_is_read_written_and_shown(tmp_path, stripes_registered):
    write_patterns(tmp_path, StripeSet(32, 16, (10, 200)))
    pattern_set = read_pattern_folder(tmp_path)
    assert pattern_set == StripeSet(32, 16, (10, 200))
    (tmp_path / "grey-200.png").unlink()  # drawn from the manifest instead
    slides, size = slides_from_path(tmp_path)
    assert size == (32, 16) and [s.name for s in slides] == ["grey-10", "grey-200"]
    assert slides[0].load()[0, 0, 0] == 10 and slides[1].load()[0, 0, 0] == 200
    (tmp_path / MANIFEST_NAME).write_text(json.dumps({"format": STRIPES, "width": 32, "height": 16}))
    with pytest.raises(InputError, match="levels"):
        read_pattern_folder(tmp_path)
