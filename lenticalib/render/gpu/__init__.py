"""GPU contexts only: OpenGL contexts, CUDA-OpenGL interop, torch devices, the monitors.

Importing this package loads nothing; each module imports what it needs.

    gl_context     offscreen OpenGL contexts (EGL first), shared by the presenter and the gl backends
    cuda_gl        CUDA-OpenGL interop: a raster made on a CUDA GPU copied into the presenter on the GPU
    torch_devices  whether a named torch device can be used, asked without starting a GPU
    monitors       the monitors a raster can be shown on (glfw), and choosing one
"""
