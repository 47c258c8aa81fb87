"""A calibrated camera from a file: mrcal ``.cameramodel`` (read by mrcal) or OpenCV YAML/JSON.

:class:`CameraModel` turns photo pixels into normalised camera rays for any lens model mrcal
knows (OPENCV4/5/8/12, splined, CAHVOR, ...), and, when the file carries mrcal's
``optimization_inputs`` (every model ``lenticalib camera calibrate`` writes does), draws
intrinsics from the calibration's own uncertainty so that poses computed with the model carry
the camera's uncertainty (:meth:`CameraModel.intrinsics_draws`).

Frames and units: photo pixels in the OpenCV/mrcal convention ((0, 0) is the centre of the
top-left pixel); the camera frame is x right, y down, z along the optical axis; normalised
coordinates are (x/z, y/z).
"""

from __future__ import annotations

import base64
import dataclasses
import io
import os
import re
import zipfile
from pathlib import Path

import numpy as np

from ...core.files.documents import read_json_file
from ...core.errors import BackendUnavailableError, InputError
from ...core.files.atomic import write_text_atomic
from ...core.files.input_files import MIB, check_input, read_input, size_text

MRCAL_INSTALL = "pip install --no-deps mrcal==2.5.2.post1 (see the README's set-up command)"
HINT = ("give an mrcal .cameramodel ('lenticalib camera calibrate' writes one) or OpenCV YAML/JSON with "
        "camera_matrix and distortion")

# LIMITS (docs/input-limits.md), checked before anything is parsed or inflated.  A calibration of
# 30 photos of a 12 x 9 board is a 70 KiB .cameramodel (some 22 bytes a corner, 25 inflated, and
# 1.3 KiB of model); mrcal decodes its base-85 optimization inputs in Python, about 9 bytes of
# memory per byte of text.
MAX_CAMERAMODEL_BYTES = 8 * MIB  # a whole .cameramodel file: some 350 000 board corners, read in ~220 MB
MAX_MODEL_TEXT_BYTES = 1 * MIB  # its model besides optimization_inputs
MAX_OPTIMIZATION_INPUTS_BYTES = 32 * MIB  # optimization_inputs' arrays inflated: some 1.3 M board corners
NOTE_KEY = "lenticalib-uncertainty-scale"  # the comment line that records the uncertainty scale
MAX_CAMERA_TEXT_BYTES = 1 * MIB  # an OpenCV YAML/XML or JSON camera model: a matrix and a few coefficients


@dataclasses.dataclass
class CameraModel:
    """A camera's lens model and intrinsics.

    ``lensmodel``: mrcal's name (``LENSMODEL_OPENCV5``, ...); OpenCV files become
    ``LENSMODEL_OPENCV4/5/8/12`` with the same coefficient order as mrcal's.  ``intrinsics``:
    (Nparams,) float64, ``fx fy cx cy`` then the distortion.  ``image_size`` (w, h) pixels or None.
    ``optimization_inputs``: mrcal's, when the file has them (for :meth:`intrinsics_draws`).
    """

    lensmodel: str
    intrinsics: np.ndarray
    image_size: tuple[int, int] | None = None
    source: str | None = None
    optimization_inputs: dict | None = None
    uncertainty_scale: float = 1.0  # from 'camera calibrate''s cross-validation (calib.intrinsics.crossval)
    _covariance_root: np.ndarray | None = dataclasses.field(default=None, init=False, repr=False, compare=False)

    @property
    def matrix(self) -> np.ndarray:
        """(3, 3) pinhole matrix of the core (fx, fy, cx, cy), pixels."""
        fx, fy, cx, cy = self.intrinsics[:4]
        return np.array([[fx, 0.0, cx], [0.0, fy, cy], [0.0, 0.0, 1.0]])

    @property
    def distortion(self) -> np.ndarray:
        """OpenCV distortion coefficients (k1 k2 p1 p2 [k3 ...]) of an OPENCV/PINHOLE model."""
        if not (self.lensmodel.startswith("LENSMODEL_OPENCV") or self.lensmodel == "LENSMODEL_PINHOLE"):
            raise InputError(f"lens model {self.lensmodel} has no OpenCV distortion vector", source=self.source)
        return self.intrinsics[4:].copy() if self.intrinsics.size > 4 else np.zeros(4)

    def normalized(self, pixels: np.ndarray, intrinsics: np.ndarray | None = None) -> np.ndarray:
        """Photo pixels (n, 2) -> normalised coordinates (n, 2) (x/z, y/z), with ``intrinsics``
        (default: the model's) -- mrcal for every lens model, OpenCV's iterative undistortion
        when mrcal is absent and the model is an OpenCV one."""
        q = np.ascontiguousarray(pixels, np.float64).reshape(-1, 2)
        params = self.intrinsics if intrinsics is None else np.asarray(intrinsics, np.float64)
        try:
            import mrcal
        except ImportError:
            mrcal = None
        if mrcal is not None:
            v = mrcal.unproject(q, self.lensmodel, params)
            return v[:, :2] / v[:, 2:3]
        import cv2

        fx, fy, cx, cy = params[:4]
        matrix = np.array([[fx, 0.0, cx], [0.0, fy, cy], [0.0, 0.0, 1.0]])
        out = cv2.undistortPointsIter(q.reshape(-1, 1, 2), matrix, params[4:] if params.size > 4 else None, None,
                                      None, (3, 100, 1e-12))
        return out.reshape(-1, 2)

    def intrinsics_draws(self, count: int, seed: int = 0) -> np.ndarray | None:
        """(count, Nparams) intrinsics drawn from the calibration's Gaussian uncertainty, or None
        when the file has no ``optimization_inputs`` (an OpenCV file: uncertainty unknown).

        Var(b) = sigma^2 D inv(J*^T J*) D over the optimised intrinsics (mrcal's packed state b*,
        unpacking scale D), sigma the RMS of the board residuals -- the observation noise mrcal
        itself estimates, times ``uncertainty_scale`` (the cross-validation of ``lenticalib camera
        calibrate``, recorded in the model's note).  Parameters the calibration held fixed (a
        splined model's core) stay.
        """
        root = self._unit_covariance_root()
        if root is None:
            return None
        rng = np.random.default_rng(seed)
        draws = np.repeat(self.intrinsics[None], count, axis=0)
        n_state = root.shape[0]
        offset = self.intrinsics.size - n_state  # a fixed core comes first
        draws[:, offset:] += self.uncertainty_scale * (rng.standard_normal((count, n_state)) @ root.T)
        return draws

    def _unit_covariance_root(self) -> np.ndarray | None:
        """A square root R (R R^T = Var) of the optimised intrinsics' covariance, before
        ``uncertainty_scale``; computed once per model (the mrcal factorisation is the costly part)."""
        if self._covariance_root is not None or self.optimization_inputs is None:
            return self._covariance_root
        import mrcal

        oi = self.optimization_inputs
        _, x, _, factorization = mrcal.optimizer_callback(**oi)
        n_state = mrcal.num_states_intrinsics(**oi)
        first = mrcal.state_index_intrinsics(0, **oi)
        if factorization is None or first is None or n_state == 0:
            return None
        n_total = mrcal.num_states(**oi)
        rows = np.zeros((n_state, n_total))
        rows[np.arange(n_state), first + np.arange(n_state)] = 1.0
        inverse = factorization.solve_xt_JtJ_bt(rows)[:, first:first + n_state]
        scale = _unpack_scale(np.ones(n_total), oi)[first:first + n_state]
        residuals = mrcal.measurements_board(oi, x=x).ravel()
        sigma = float(np.sqrt(np.mean(residuals ** 2))) if residuals.size else 0.0
        cov = sigma ** 2 * (scale[:, None] * inverse * scale[None, :])
        w, v = np.linalg.eigh(0.5 * (cov + cov.T))
        self._covariance_root = v * np.sqrt(np.clip(w, 0.0, None))
        return self._covariance_root


def note_line(scale: float) -> str:
    """The note line that records ``scale`` in the written .cameramodel."""
    return f"{NOTE_KEY}: {scale:.4f}"


def read_scale(text: str) -> float:
    """The recorded scale (:mod:`.intrinsics.crossval`) from a .cameramodel's leading comment lines (1.0 when absent).  Only the
    header comments are looked at; the model itself is read by mrcal."""
    for line in text.splitlines():
        stripped = line.strip()
        if not stripped.startswith("#"):
            if stripped:
                break
            continue
        body = stripped.lstrip("#").strip()
        if body.startswith(NOTE_KEY + ":"):
            try:
                value = float(body.split(":", 1)[1])
            except ValueError:
                return 1.0
            return value if np.isfinite(value) and 1.0 <= value <= 100.0 else 1.0
    return 1.0


def _unpack_scale(packed: np.ndarray, oi: dict) -> np.ndarray:
    """mrcal's packed (unitless) state -> real units, on a copy (mrcal scales in place)."""
    import mrcal

    out = packed.copy()
    mrcal.unpack_state(out, **oi)
    return out


def load_camera_model(path: str | os.PathLike) -> CameraModel:
    """Read a camera model: ``.cameramodel`` by mrcal (every lens model it knows; no other parser),
    ``.yaml/.yml/.xml`` by ``cv2.FileStorage``, anything else as JSON
    (``camera_matrix``, ``distortion``, optional ``image_size``).  Every failure is one
    InputError naming the file; a missing mrcal is a BackendUnavailableError saying how to install it.

    Each is a regular file within its cap (:data:`MAX_CAMERAMODEL_BYTES`,
    :data:`MAX_CAMERA_TEXT_BYTES`), checked before it is read; a ``.cameramodel``'s structure is
    checked before mrcal parses it (:func:`check_cameramodel_text`).
    """
    path = Path(path)
    if not os.path.lexists(path):
        raise InputError("camera model not found", source=str(path), hint="give an existing .cameramodel or .yaml")
    try:
        if path.suffix == ".cameramodel":
            return _from_mrcal(path)
        if path.suffix in (".yaml", ".yml", ".xml"):
            check_input(path, "camera model", MAX_CAMERA_TEXT_BYTES, HINT)
            return _from_opencv_storage(path)

        try:
            data = read_json_file(path, "camera model", HINT, max_bytes=MAX_CAMERA_TEXT_BYTES)
        except InputError as exc:
            raise InputError(f"cannot read the camera model ({exc.message})", source=str(path), hint=HINT) from None
        matrix = np.asarray(data["camera_matrix"], float).reshape(3, 3)
        dist = np.asarray(data.get("distortion", [0, 0, 0, 0]), float).ravel()
        return _opencv_model(matrix, dist, tuple(data["image_size"]) if "image_size" in data else None, path)
    except (InputError, BackendUnavailableError):
        raise
    except Exception as exc:  # any parse failure of a user file is a user error
        reason = str(exc).strip().splitlines()[-1][:160] if str(exc).strip() else type(exc).__name__
        raise InputError(f"cannot read the camera model ({reason})", source=str(path), hint=HINT) from None


# mrcal writes the optimization inputs as one base-85 bytes literal (no quote or backslash inside)
_OPTIMIZATION_INPUTS = re.compile(r"""(['"])optimization_inputs\1\s*:\s*b(['"])([^'"\\]*)\2""")


def check_cameramodel_text(text: str, source: str) -> None:
    """Refuse, before mrcal parses it, a ``.cameramodel`` text whose structure no calibration has.

    The model without its ``optimization_inputs`` (a Python literal mrcal reads with
    ``ast.literal_eval``) must fit :data:`MAX_MODEL_TEXT_BYTES`; ``optimization_inputs``, when
    present, must be one base-85 bytes literal, and the zip archive it encodes must list members
    whose uncompressed sizes (from its central directory: what inflating them produces at most)
    add up to at most :data:`MAX_OPTIMIZATION_INPUTS_BYTES`.  Nothing is inflated here.
    """
    match = _OPTIMIZATION_INPUTS.search(text)
    if match is None and "optimization_inputs" in text:
        raise InputError("cannot read the camera model ('optimization_inputs' is not mrcal's base-85 bytes literal)",
                         source=source, hint=HINT)
    model_bytes = len(text) - (len(match[3]) if match else 0)
    if model_bytes > MAX_MODEL_TEXT_BYTES:
        raise InputError(f"cannot read the camera model (it holds {size_text(model_bytes)} of text besides "
                         f"'optimization_inputs', more than any lens model needs: at most "
                         f"{size_text(MAX_MODEL_TEXT_BYTES)})", source=source, hint=HINT)
    if match is None:
        return
    try:
        members = zipfile.ZipFile(io.BytesIO(base64.b85decode(match[3]))).infolist()
    except (ValueError, zipfile.BadZipFile, EOFError, NotImplementedError) as exc:
        reason = " ".join(str(exc).split())[:80] or type(exc).__name__
        raise InputError(f"cannot read the camera model ('optimization_inputs' is not an archive mrcal wrote: "
                         f"{reason})", source=source, hint=HINT) from None
    total = sum(info.file_size for info in members)
    if total > MAX_OPTIMIZATION_INPUTS_BYTES:
        raise InputError(f"cannot read the camera model ('optimization_inputs' inflates to {size_text(total)}, more "
                         f"than a calibration's observations hold: at most {size_text(MAX_OPTIMIZATION_INPUTS_BYTES)})",
                         source=source, hint=HINT)


def _from_mrcal(path: Path) -> CameraModel:
    source = str(path)
    text = read_input(path, "camera model", MAX_CAMERAMODEL_BYTES, HINT).decode("utf-8", errors="replace")
    check_cameramodel_text(text, source)
    try:
        import mrcal
    except ImportError:
        raise BackendUnavailableError("reading a .cameramodel needs mrcal, which is not installed", source=source,
                                      hint=MRCAL_INSTALL) from None
    model = mrcal.cameramodel(io.StringIO(text))  # the text checked, not the path read again
    lensmodel, intrinsics = model.intrinsics()
    size = model.imagersize()
    try:
        oi = model.optimization_inputs()
    except Exception:  # a model without (or with unusable) optimization inputs is still a model
        oi = None
    return CameraModel(lensmodel, np.asarray(intrinsics, np.float64).copy(),
                       None if size is None else (int(size[0]), int(size[1])), source, oi, read_scale(text))


def _opencv_model(matrix: np.ndarray, dist: np.ndarray, size, path: Path) -> CameraModel:
    """An OpenCV matrix + distortion as the mrcal lens model with the same coefficients."""
    if matrix[0, 1] != 0 or matrix[1, 0] != 0 or matrix[2, 0] != 0 or matrix[2, 1] != 0:
        raise InputError("the camera matrix has skew, which no lens model here supports", source=str(path))
    counts = {0: 4, 4: 4, 5: 5, 8: 8, 12: 12}
    if dist.size not in counts:
        raise InputError(f"{dist.size} distortion coefficients", source=str(path),
                         hint="give 4, 5, 8 or 12 OpenCV coefficients (k1 k2 p1 p2 [k3 [k4 k5 k6 [s1..s4]]])")
    n = counts[dist.size]
    full = np.zeros(n)
    full[:dist.size] = dist
    intrinsics = np.concatenate([[matrix[0, 0], matrix[1, 1], matrix[0, 2], matrix[1, 2]], full])
    return CameraModel(f"LENSMODEL_OPENCV{n}", intrinsics, size, str(path))


def _from_opencv_storage(path: Path) -> CameraModel:
    import cv2

    fs = cv2.FileStorage(str(path), cv2.FILE_STORAGE_READ)
    try:
        matrix = fs.getNode("camera_matrix").mat()
        dist = fs.getNode("distortion_coefficients").mat()
        if dist is None:
            dist = fs.getNode("distortion").mat()
        width, height = fs.getNode("image_width").real(), fs.getNode("image_height").real()
    finally:
        fs.release()
    if matrix is None:
        raise InputError("has no camera_matrix", source=str(path), hint="write it with cv2.FileStorage")
    size = (int(width), int(height)) if width > 0 and height > 0 else None
    return _opencv_model(np.asarray(matrix, float), np.zeros(4) if dist is None else np.asarray(dist, float).ravel(),
                         size, path)


def write_cameramodel(model, path: str | os.PathLike, note: str | None = None) -> Path:
    """Write ``model`` with mrcal's writer (``note`` goes into the file's header comment) and put it
    in place atomically (:func:`lenticalib.core.files.atomic.write_text_atomic`: an earlier file survives any
    failure)."""
    text = io.StringIO()
    model.write(text, note=note)
    return write_text_atomic(path, text.getvalue())
