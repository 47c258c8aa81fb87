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
    └── BackendUnavailableError (ImportError)  a registered backend whose module will not load
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
