"""``encode_to_file``: views (a folder or a quilt) + profile -> a panel raster file, in one call.

The work of ``lenticalib encode``: the profile, the encoder, the crosstalk pre-compensation and
the output path are checked before the views are read; the views are read (a folder of N
images, or a quilt), optionally pre-compensated (:class:`CompensationOptions`), encoded
(:func:`lenticalib.render.encoders.encode`) and written (:func:`lenticalib.core.files.imageio.write_image`).

Errors name the argument at fault by its parameter name (``source="black_lift"``; hints mention
``crosstalk_file`` and ``allow_stretch``); a command-line front end maps them to its flags.
"""

from __future__ import annotations

import dataclasses
import os
import time
from pathlib import Path

import numpy as np

from ...core.errors import ImageError, InputError
from ...core.identity import profile_identity
from ...core.files.imageio import check_image_output, write_image
from ...core.profile import PanelProfile, load_profile
from ..compose.compensation import (DEFAULT_ITERATIONS, DEFAULT_REGULARISATION, Compensator,
    compensator_from_file)


@dataclasses.dataclass(frozen=True)
class CompensationOptions:
    """Pre-compensation of the views for the crosstalk in ``crosstalk_file`` (``crosstalk.json``
    of a crosstalk measurement): ``black_lift`` (linear, 0..0.5), ``regularisation`` (default
    0.02), ``iterations`` (default 2); see :class:`~.compensation.Compensator`.  ``force``: use a
    crosstalk file measured for another panel (``docs/identity.md``; the compensator's ``origin``
    then says so).  No ``crosstalk_file``: no compensation (and the other fields must stay at their
    defaults)."""

    crosstalk_file: str | os.PathLike | None = None
    black_lift: float = 0.0
    regularisation: float | None = None
    iterations: int | None = None
    force: bool = False

    def compensator(self, profile: PanelProfile) -> Compensator | None:
        """The compensator for the panel of ``profile``, or None; InputError naming the field for a
        setting without ``crosstalk_file`` or out of range, or naming the file when it was measured
        for another panel (unless ``force``)."""
        if self.crosstalk_file is None:
            for field, value, default in (("black_lift", self.black_lift, 0.0),
                                          ("regularisation", self.regularisation, None),
                                          ("iterations", self.iterations, None), ("force", self.force, False)):
                if value != default:
                    raise InputError("is only used with crosstalk_file", source=field, hint="add crosstalk_file")
            return None
        return compensator_from_file(self.crosstalk_file, profile,
                                     DEFAULT_REGULARISATION if self.regularisation is None else self.regularisation,
                                     self.black_lift, DEFAULT_ITERATIONS if self.iterations is None else self.iterations,
                                     source=str(self.crosstalk_file), force=self.force)


@dataclasses.dataclass
class EncodedFile:
    """What :func:`encode_to_file` wrote: ``output``; the ``profile``; ``view_size`` (W_v, H_v);
    ``dtype`` of the raster; the ``encoder``; ``encode_seconds`` (incl. a first compile) and
    ``compensate_seconds`` (None: no compensation, or done by the encoder on its device (``gl``)
    and counted in ``encode_seconds``); ``crosstalk_file``; ``compensation_origin``: the
    compensator's ``origin`` (the file, the panel it was measured for, whether it was forced)."""

    output: Path
    profile: PanelProfile
    view_size: tuple[int, int]
    dtype: str
    encoder: str
    encode_seconds: float
    compensate_seconds: float | None
    crosstalk_file: str | None
    compensated_on: str | None = None  # "host", "gpu" (the encoder's device), None: not compensated
    compensation_origin: dict | None = None

    @property
    def provenance(self) -> dict:
        """What the raster was made from: the profile's identity and, with compensation, the
        crosstalk file, the panel it was measured for and whether that was forced."""
        record = {"profile_id": profile_identity(self.profile)}
        if self.compensation_origin is not None:
            record["compensation"] = dict(self.compensation_origin)
        return record

    def summary(self) -> dict:
        """The JSON summary ``lenticalib encode --json`` prints."""
        p = self.profile
        return {"output": str(self.output), "width": p.width, "height": p.height, "views": p.views,
                "view_size": list(self.view_size), "dtype": self.dtype, "encoder": self.encoder,
                "encode_seconds": round(self.encode_seconds, 4), "compensate": self.crosstalk_file,
                "compensate_seconds": None if self.compensate_seconds is None else round(self.compensate_seconds, 4),
                "compensated_on": self.compensated_on, "provenance": self.provenance}


def encode_to_file(profile: PanelProfile | str | os.PathLike, output: str | os.PathLike, *,
                   views_dir: str | os.PathLike | None = None, quilt: str | os.PathLike | None = None,
                   grid=None, encoder: str = "fast", allow_stretch: bool = False,
                   compensation: CompensationOptions | None = None) -> EncodedFile:
    """Encode the views of ``views_dir`` (N images, natural file-name order) or ``quilt`` (view 0
    bottom-left; ``grid``, a :class:`~.views.QuiltGrid`, when its name has no ``_qsCOLSxROWS`` suffix) into the
    raster of ``profile`` (a profile or its JSON file) and write it to ``output`` (.png, .tif or
    .npy).  ``allow_stretch``: views of another aspect ratio than the panel's are stretched.
    Returns :class:`EncodedFile`; InputError/ImageError before any work for a bad argument.
    """
    from ..encoders import compensates_on_device, encode, get_encoder
    from ..compose.views import load_quilt, load_view_folder

    if (views_dir is None) == (quilt is None):
        raise InputError("give the views one way", source="views_dir", hint="either views_dir or quilt")
    compensation = compensation or CompensationOptions()
    inputs = (None if isinstance(profile, PanelProfile) else profile, views_dir, quilt, compensation.crosstalk_file)
    if not isinstance(profile, PanelProfile):
        profile = load_profile(profile, "`profile`")
    get_encoder(encoder)  # an unknown encoder is refused before the views are read
    # a wrong output path costs nothing
    check_image_output(output, what="panel raster", example="raster.png", inputs=inputs)
    compensator = compensation.compensator(profile)
    if quilt is not None:
        views, found = load_quilt(quilt, profile.views, grid)
        panel_aspect = profile.width / profile.height
        if found.aspect and not allow_stretch and abs(found.aspect / panel_aspect - 1.0) > 0.01:
            raise ImageError(f"quilt was made for aspect {found.aspect:g}, the profile's panel is "
                             f"{profile.width}x{profile.height} (aspect {panel_aspect:.4f})", source=str(quilt),
                             hint="use the profile of the panel the quilt was made for, or allow_stretch")
    else:
        views = load_view_folder(views_dir, profile.views)
    # e.g. float views into a .png
    check_image_output(output, views.dtype, what="panel raster", example="raster.png", inputs=inputs)
    compensate_seconds = None
    on_device = False
    if compensator is not None:
        if views.dtype != np.uint8:
            raise ImageError(f"compensation works on 8-bit views, these are {views.dtype}",
                             source=str(views_dir if views_dir is not None else quilt),
                             hint="save the views as 8-bit PNG or JPEG")
        on_device = compensates_on_device(encoder)
        if not on_device:
            start = time.perf_counter()
            views = compensator.apply(views)
            compensate_seconds = time.perf_counter() - start
    start = time.perf_counter()
    raster = encode(views, profile, encoder, allow_stretch=allow_stretch,
                    compensator=compensator if on_device else None)
    elapsed = time.perf_counter() - start
    write_image(output, raster)
    return EncodedFile(Path(output), profile, (int(views.shape[2]), int(views.shape[1])), str(raster.dtype), encoder,
                       elapsed, compensate_seconds,
                       None if compensation is None or compensation.crosstalk_file is None
                       else str(compensation.crosstalk_file),
                       None if compensator is None else "gpu" if on_device else "host",
                       None if compensator is None else compensator.origin)
