"""CUDA-OpenGL interop: a raster made on a CUDA GPU copied into an OpenGL pixel buffer on the GPU.

The ``gsplat`` renderer and the ``torch`` encoder leave the panel raster on the CUDA device; the
presenter needs it in an OpenGL texture.  Through host memory that is two copies of 25 MB per 4K
frame (an H100 took 0.5 ms to copy it out to page-locked memory and 4-7 ms to copy it into a pixel
buffer); through this module it is one copy on the GPU.  A pixel-buffer object of the presenter's
context is registered with CUDA once (``cuGraphicsGLRegisterBuffer``), and each frame is mapped,
filled with ``cuMemcpyDtoDAsync`` on the torch stream that made the raster, and unmapped, which
orders the copy before any OpenGL command issued afterwards.

It needs the OpenGL context on the same GPU as CUDA (an NVIDIA driver's context, EGL or GLX), the
driver library ``libcuda.so.1`` and the torch tensor on that GPU.  Anything else (Mesa, another
vendor's GPU, a second GPU) raises :class:`~lenticalib.core.errors.DisplayError` at registration,
and the presenter goes through host memory instead.
"""

from __future__ import annotations

import ctypes

from ...core.errors import DisplayError

WRITE_DISCARD = 2  # CU_GRAPHICS_REGISTER_FLAGS_WRITE_DISCARD: CUDA only writes, OpenGL only reads
_LIBRARY = []  # the driver library, loaded once


def _driver():
    if not _LIBRARY:
        try:
            lib = ctypes.CDLL("libcuda.so.1")
        except OSError as exc:
            raise DisplayError(f"no CUDA driver library for OpenGL interop ({exc})") from None
        handle, pointer, size, uint = ctypes.c_void_p, ctypes.POINTER(ctypes.c_void_p), ctypes.c_size_t, ctypes.c_uint
        signatures = {
            "cuGraphicsGLRegisterBuffer": (pointer, uint, uint),
            "cuGraphicsUnregisterResource": (handle,),
            "cuGraphicsMapResources": (uint, pointer, handle),
            "cuGraphicsUnmapResources": (uint, pointer, handle),
            "cuGraphicsResourceGetMappedPointer_v2": (ctypes.POINTER(ctypes.c_uint64), ctypes.POINTER(size), handle),
            "cuMemcpyDtoDAsync_v2": (ctypes.c_uint64, ctypes.c_uint64, size, handle),
        }
        for name, args in signatures.items():
            function = getattr(lib, name)
            function.argtypes, function.restype = list(args), ctypes.c_int
        _LIBRARY.append(lib)
    return _LIBRARY[0]


def _check(code: int, call: str) -> None:
    if code != 0:
        raise DisplayError(f"CUDA-OpenGL interop: {call} failed (CUDA error {code})")


class RegisteredBuffer:
    """An OpenGL buffer (moderngl ``Buffer``, its context current) that CUDA writes into.
    :meth:`copy_from` fills it from a contiguous CUDA tensor; :meth:`release` before the buffer."""

    def __init__(self, buffer):
        self._lib = _driver()
        self._resource = ctypes.c_void_p()
        self.nbytes = int(buffer.size)
        _check(self._lib.cuGraphicsGLRegisterBuffer(ctypes.byref(self._resource), int(buffer.glo), WRITE_DISCARD),
               "cuGraphicsGLRegisterBuffer")

    def copy_from(self, tensor) -> None:
        """Copy ``tensor`` (contiguous, on the CUDA device of this context, at most the buffer's
        size in bytes) into the buffer, ordered on the current torch stream and before any later
        OpenGL command."""
        import torch

        nbytes = tensor.numel() * tensor.element_size()
        if nbytes > self.nbytes or not tensor.is_cuda or not tensor.is_contiguous():
            raise DisplayError(f"CUDA-OpenGL interop: a raster of {nbytes} bytes (contiguous on CUDA) does not "
                               f"fit the {self.nbytes}-byte pixel buffer")
        stream = ctypes.c_void_p(torch.cuda.current_stream(tensor.device).cuda_stream)
        resource = self._resource
        _check(self._lib.cuGraphicsMapResources(1, ctypes.byref(resource), stream), "cuGraphicsMapResources")
        try:
            address, size = ctypes.c_uint64(), ctypes.c_size_t()
            _check(self._lib.cuGraphicsResourceGetMappedPointer_v2(ctypes.byref(address), ctypes.byref(size), resource),
                   "cuGraphicsResourceGetMappedPointer")
            _check(self._lib.cuMemcpyDtoDAsync_v2(address.value, tensor.data_ptr(), nbytes, stream), "cuMemcpyDtoDAsync")
        finally:
            _check(self._lib.cuGraphicsUnmapResources(1, ctypes.byref(resource), stream), "cuGraphicsUnmapResources")

    def release(self) -> None:
        if self._resource:
            self._lib.cuGraphicsUnregisterResource(self._resource)
            self._resource = ctypes.c_void_p()


class DeviceUploads:
    """Two pixel buffers of ``nbytes`` in the moderngl context ``ctx`` (current), registered with
    CUDA and used in turn: :meth:`upload` fills the next from a CUDA tensor and returns it for a
    ``texture.write``.  DisplayError where the driver cannot share them (see the module's text)."""

    def __init__(self, ctx, nbytes: int):
        self.buffers = [ctx.buffer(reserve=int(nbytes)) for _ in range(2)]
        self.registered: list[RegisteredBuffer] = []
        try:
            for buffer in self.buffers:
                self.registered.append(RegisteredBuffer(buffer))
        except DisplayError:
            self.release()
            raise
        self._next = 0

    def upload(self, tensor):
        """The next pixel buffer, filled with ``tensor`` (contiguous, on the CUDA device)."""
        index, self._next = self._next, 1 - self._next
        self.registered[index].copy_from(tensor)
        return self.buffers[index]

    def release(self) -> None:
        for registered in self.registered:
            registered.release()
        for buffer in self.buffers:
            buffer.release()
        self.registered, self.buffers = [], []
