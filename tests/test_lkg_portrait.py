"""A Looking Glass Portrait plays with the README's own commands (issue 46, part 2).

Defaults follow the panel: a Looking Glass profile takes the quilt Looking Glass renders for its
model (from the calibration's serial, lenticalib.core.looking_glass.models), any other profile a view size
at its aspect; a view size of another aspect is refused in one line whose hint names sizes that
then work.
"""

from __future__ import annotations

import re

import numpy as np
import pytest

from lenticalib.core.looking_glass.models import QUILT_MODELS, model_for_serial
from lenticalib.core.profile import load_profile
from lenticalib.core.view_defaults import (DEFAULT_VIEW_SIZE, aspect_error, default_camera_arc, default_view_size,
                                           fitting_size)

from .cli_support import refused, run_main
from .looking_glass_support import CELLS, visual_bytes

PANEL_4K = "fixtures/panel-4k-32.json"
ENCODERS_TOLERANCE = 0.01  # lenticalib.render.encoders.common.ASPECT_TOLERANCE


@pytest.fixture(scope="module")
def portrait(tmp_path_factory):
    """An emulated Portrait's visual.json, its profile as the README makes it (device read, no
    --views) and a small demo avatar: (folder, profile path, avatar path)."""
    from lenticalib.render.avatar.demo_avatar import make_demo_avatar
    from lenticalib.render.avatar.rig_file import save_rig

    folder = tmp_path_factory.mktemp("portrait")
    (folder / "visual.json").write_bytes(visual_bytes(CELLS))  # serial LKG-P-01234, 1536x2048
    save_rig(folder / "demo.npz", make_demo_avatar(seed=1, count=2000))
    with pytest.MonkeyPatch.context() as patch:
        patch.setenv("LENTICALIB_EMULATOR_DIR", str(folder / "emu"))
        code, out, err = run_main("emulate", "--looking-glass", folder / "visual.json", "--name", "portrait")
        assert code == 0, err
        code, out, err = run_main("device", "read", "lkg-emu://portrait", "-o", folder / "lkg.json")
    assert code == 0, err
    assert "48 views, 1536x2048" in out
    return folder, folder / "lkg.json", folder / "demo.npz"


def test_the_vendor_table():
    """The quilts of looking-glass-webxr's LookingGlassConfig.ts, by serial prefix."""
    quilts = {m.prefix: (m.quilt_width, m.quilt_height, m.columns, m.rows) for m in QUILT_MODELS}
    assert quilts["LKG-P"] == (3360, 3360, 8, 6) and quilts["LKG-E"] == (4092, 4092, 11, 6)
    assert quilts["LKG-2K"] == quilts["LKG-4K"] == (4096, 4096, 5, 9) and quilts["LKG-D"] == (8192, 8192, 8, 9)
    assert quilts["LKG-H"] == (5995, 6000, 11, 6) and quilts["LKG-L"] == (8190, 8190, 7, 7)
    assert model_for_serial("LKG-P03996").views == 48 and model_for_serial("LKG-P03996").tile_size == (420, 560)
    assert model_for_serial("LKG-2K-04321").views == 45 and model_for_serial("LKG-E01234").views == 66
    for serial in ("", "ACME-P1", "lkg-p03996", None, 42, "XLKG-P"):
        assert model_for_serial(serial) is None, serial


def test_defaults_follow_the_panel(portrait):
    _, lkg, _ = portrait
    profile = load_profile(lkg)
    assert profile.views == 48 and default_view_size(profile) == (420, 560)  # the Portrait's quilt tile
    assert default_camera_arc(profile) == 40.0  # the calibration's viewCone
    four_k = load_profile(PANEL_4K)
    assert default_view_size(four_k) == DEFAULT_VIEW_SIZE == (960, 540) and default_camera_arc(four_k) == 50.0
    assert default_view_size(four_k.replace(width=1536, height=2048)) == (624, 832)  # a 3:4 panel, no model
    for model in QUILT_MODELS:  # every model's default fits its panel shape
        for panel in ((1536, 2048), (1440, 2560), (3840, 2160), (2560, 1600), (7680, 4320)):
            other = profile.replace(width=panel[0], height=panel[1], looking_glass={"serial": model.prefix + "0"})
            size = default_view_size(other)
            assert size[1] == model.tile_size[1] or aspect_error(size, panel) <= 0.005, (model, panel, size)
            assert aspect_error(size, panel) <= 0.005


def test_hint_sizes_fit_every_panel():
    """A size proposed after a wrong one fits the panel's aspect and is no larger than the one asked."""
    rng = np.random.default_rng(46)
    base = load_profile(PANEL_4K)
    for _ in range(300):
        panel = tuple(int(v) for v in rng.integers(64, 8193, 2))
        asked = tuple(int(v) for v in rng.integers(8, 2049, 2))
        fit = fitting_size(base.replace(width=panel[0], height=panel[1]), asked)
        assert aspect_error(fit, panel) <= ENCODERS_TOLERANCE, (panel, asked, fit)
        assert fit[0] * fit[1] <= asked[0] * asked[1] * 1.1 + 64, (panel, asked, fit)


def test_readme_commands_play_render_show_on_a_portrait(portrait, tmp_path):
    folder, lkg, demo = portrait
    # lenticalib play avatar --profile lkg.json (offscreen, one frame): the Portrait's quilt views
    code, out, err = run_main("play", demo, "--profile", lkg, "--display", "offscreen", "--frames", 1)
    assert code == 0, err
    assert "48 views 420x560" in out and "panel 1536x2048" in out
    # a 16:9 size on the Portrait: one line, before the avatar is read; its hint names a size that fits
    line = refused("render", demo, "--profile", lkg, "-o", tmp_path / "x.png", "--view-size", "96x54",
                   source="--view-size")
    assert "do not fit the 1536x2048 panel" in line and "420x560" in line and "16:9" not in line
    proposed = re.search(r"e\.g\. (\d+x\d+)", line).group(1)
    assert proposed == "42x56"
    code, out, err = run_main("render", demo, "--profile", lkg, "-o", tmp_path / "frame.png", "--view-size", proposed)
    assert code == 0, err
    assert f"48 views {proposed}" in out and (tmp_path / "frame.png").is_file()
    # a pre-made quilt: encode --quilt quilt_qs8x6a0.75.png, then show the frame
    from lenticalib.core.files.imageio import write_image

    quilt = tmp_path / "quilt_qs8x6a0.75.png"
    write_image(quilt, np.random.default_rng(0).integers(0, 256, (6 * 56, 8 * 42, 3), dtype=np.uint8))
    code, out, err = run_main("encode", "--profile", lkg, "--quilt", quilt, "-o", tmp_path / "enc.png")
    assert code == 0, err
    code, out, err = run_main("show", tmp_path / "enc.png", "--display", "offscreen", "--interval", 0.01)
    assert code == 0, err
    assert "showed 1 raster(s) of 1536x2048" in out
    # show --profile plays the quilt itself; one named without _qs is the model's quilt (8x6 on a Portrait)
    plain = tmp_path / "quilt.png"
    plain.write_bytes(quilt.read_bytes())
    for path in (quilt, plain):
        code, out, err = run_main("show", path, "--profile", lkg, "--display", "offscreen", "--interval", 0.01)
        assert code == 0, err
        assert "1 frame(s) presented, 0 dropped" in out


def test_a_4k_profile_keeps_960x540(portrait, tmp_path):
    from lenticalib.render.pipeline.session import open_avatar_session

    _, lkg, demo = portrait
    session = open_avatar_session(demo, PANEL_4K)
    assert (session.pipeline.cameras.width, session.pipeline.cameras.height) == (960, 540)
    assert float(np.ptp(session.pipeline.cameras.yaw_deg)) == pytest.approx(50.0)
    session.close()
    session = open_avatar_session(demo, lkg)
    assert (session.pipeline.cameras.width, session.pipeline.cameras.height) == (420, 560)
    assert float(np.ptp(session.pipeline.cameras.yaw_deg)) == pytest.approx(40.0)  # the viewCone's arc
    session.close()


def test_views_default_from_the_model(portrait, tmp_path):
    folder, lkg, _ = portrait
    code, out, err = run_main("profile", "import-lkg", folder / "visual.json", "-o", tmp_path / "p.json")
    assert code == 0, err
    assert load_profile(tmp_path / "p.json").views == 48
    unknown = tmp_path / "visual.json"
    unknown.write_bytes(visual_bytes(dict(CELLS, serial="ACME-1")))
    line = refused("profile", "import-lkg", unknown, "-o", tmp_path / "q.json", source="--views")
    assert "names no model" in line and not (tmp_path / "q.json").exists()
    # a unit whose calibration has no serial: its USB serial (here LKG-EMU-...) names no model
    no_serial = {k: v for k, v in CELLS.items() if k != "serial"}
    unknown.write_bytes(visual_bytes(no_serial))
    with pytest.MonkeyPatch.context() as patch:
        patch.setenv("LENTICALIB_EMULATOR_DIR", str(tmp_path / "emu"))
        assert run_main("emulate", "--looking-glass", unknown, "--name", "anonymous")[0] == 0
        line = refused("device", "read", "lkg-emu://anonymous", "-o", tmp_path / "q.json", source="--views")
        assert "names no model" in line
        code, out, err = run_main("device", "read", "lkg-emu://anonymous", "-o", tmp_path / "q.json", "--views", 45)
        assert code == 0 and load_profile(tmp_path / "q.json").views == 45, err
