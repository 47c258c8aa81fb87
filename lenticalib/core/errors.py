"""The one exception tree of lenticalib.

Every error a user can cause (a bad file, a missing field, an image of the wrong
size) is a :class:`LenticalibError`; the CLI prints its message on one line and
exits non-zero.  Anything else escaping the library is a bug.

    LenticalibError
    ├── InputError (ValueError)          bad user input: files, fields, arrays
    │   ├── ProfileError                 a panel profile that does not load or validate
    │   ├── ImageError                   an image or view set that cannot be used
    │   └── CaptureError                 a capture set (photos of the test patterns) that cannot be used
    ├── CalibrationError                 a fit that fails or cannot be trusted
    ├── ConfigurationError (ValueError)  a valid-looking setup the encoder cannot honour
    ├── BackendUnavailableError (ImportError)  a registered backend whose module will not load
    ├── DisplayError                     no display, an unknown monitor, a window or GL context that will not open
    ├── CameraError                      a camera that cannot be opened, configured or triggered
    └── DeviceError                      a panel controller that cannot be reached or misbehaves
        ├── DeviceNotFoundError          no device at that URL (unplugged, no permission, bad URL)
        ├── DeviceTimeoutError (TimeoutError)  no valid reply within the timeout, after retries
        ├── DeviceDisconnectedError      the link went away mid-transfer (cable, power)
        └── DeviceProtocolError          the controller answered with an error code or a bad record
"""

from __future__ import annotations


class LenticalibError(Exception):
    """Root of every error lenticalib raises on purpose.

    ``source`` names the file or field at fault (or is ``None``); ``hint`` says what
    to do.  ``str(err)`` is the complete one-line message.
    """

    def __init__(self, message: str, *, source: str | None = None, hint: str | None = None):
        self.message = message
        self.source = source
        self.hint = hint
        super().__init__(message, source, hint)

    def __str__(self) -> str:
        text = f"{self.source}: {self.message}" if self.source else self.message
        if self.hint:
            text += f" ({self.hint})"
        return text

    def __reduce__(self):
        return (_rebuild, (type(self), self.message, self.source, self.hint))


def _rebuild(cls, message, source, hint):
    return cls(message, source=source, hint=hint)


class InputError(LenticalibError, ValueError):
    """Bad user input: a file, a field or an array that cannot be used as given."""


class ProfileError(InputError):
    """A panel profile that cannot be loaded, parsed or validated."""


class ImageError(InputError):
    """An image, a folder of views or a quilt that cannot be used."""


class CaptureError(InputError):
    """A capture set that cannot be used: a missing, extra, wrong, black, clipped or blurred photo."""


class CalibrationError(LenticalibError):
    """A fit that did not converge or whose result cannot be trusted (too uncertain, bad residual)."""


class ConfigurationError(LenticalibError, ValueError):
    """A configuration the encoder cannot honour (e.g. more than two views on one subpixel)."""


class BackendUnavailableError(LenticalibError, ImportError):
    """A registered backend (encoder, transport) whose implementation cannot be loaded."""


class DisplayError(LenticalibError):
    """No display to show on, an unknown monitor, or a window / GL context that will not open."""


class CameraError(LenticalibError):
    """A camera (tethered, webcam, watched folder, virtual) that cannot be opened, configured or triggered."""


class DeviceError(LenticalibError):
    """A panel controller that cannot be reached, times out or answers with an error.

    ``code`` is the firmware status code when the controller sent one (else ``None``).
    """

    def __init__(self, message: str, *, source: str | None = None, hint: str | None = None,
                 code: int | None = None):
        super().__init__(message, source=source, hint=hint)
        self.code = code

    def __reduce__(self):
        return (_rebuild_device, (type(self), self.message, self.source, self.hint, self.code))


def _rebuild_device(cls, message, source, hint, code):
    return cls(message, source=source, hint=hint, code=code)


class DeviceNotFoundError(DeviceError):
    """No device at the URL: unplugged, no permission, no such path, or a malformed URL."""


class DeviceTimeoutError(DeviceError, TimeoutError):
    """No valid reply within the command's timeout, after every retry."""


class DeviceDisconnectedError(DeviceError):
    """The link went away during a transfer (cable pulled, controller lost power)."""


class DeviceProtocolError(DeviceError):
    """The controller answered with an error status, or sent a record that does not decode."""
