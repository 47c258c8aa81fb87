"""The render layer: from a Gaussian avatar and a calibrated profile to pixels on the panel.

render imports only core (and itself).  Importing this package loads nothing; modules import
numpy, numba, torch, OpenCV, glfw and moderngl themselves, most only when used.

Views to the panel raster
    views               view inputs: a folder of N images, or a quilt (tiles, view 0 bottom-left)
    sampling            where each subpixel samples its view, and which view(s) it shows
    encoders            N views ``(N, H_v, W_v, 3)`` -> one panel raster, by name (lazy registry)
    compensation        crosstalk pre-compensation: views sent so that each eye sees what it should
    encode_file         ``encode_to_file``: views + profile -> a panel raster file, in one call

Cameras and renderers
    cameras             the N virtual cameras: container, projection, view order, ``cameras.json``
    camera_models       the arc and shear camera models, selected by name (``make_cameras``)
    renderers           Gaussians + N cameras -> N RGBA views, by name (lazy registry)
    torch_devices       whether a named torch device can be used, asked without starting a GPU

The avatar
    gaussians           a set of 3D Gaussians, as every renderer and deformer takes it
    ply                 the standard 3DGS PLY file (INRIA 3DGS and gsplat layout)
    rig                 a rig (Gaussians + blendshapes + bones), its control layout, its deformer
    rig_deform          the deformation kernels a rig and its mesh share: quaternions, blendshapes, blended bones
    rig_file            the rig as a numpy ``.npz``: read, validated, written
    demo_avatar         the built-in demo head (about 100k Gaussians) as a rig
    demo_avatar_parts   the demo head's parts: where their Gaussians sit, colours, bones
    demo_avatar_shapes  the demo head's geometry: surfaces and sampling them with Gaussians
    demo_avatar_mesh    the demo head's triangle mesh (skin, eyes, ears, neck, collar), skinned
    mesh                triangle meshes of avatars: OBJ and PLY files, the fit to an avatar's box
    rig_mesh            the mesh a rig carries, skinned and blendshaped like its Gaussians
    avatar              an avatar to render: a PLY, a rig file, or a rig with a plug-in driver
    drivers             avatar drivers: a control vector -> posed Gaussians, frame by frame
    controls            control sources: ``latest(now)``, control files, the source for a spec
    control_records     one JSON control record, as control files and live streams carry it
    control_streams     live and built-in sources: the demo motion, JSON lines on stdin or UDP
    student             the student driver: a network trained per subject, camera frames -> controls

Presenting and the pipeline
    present             pixel-exact full-screen presentation (glfw + moderngl): ``Presenter``
    present_base        the presenters' base: ``Presenter``, ``FrameTiming``, ``RASTER_HINT``
    present_offscreen   presenters with no window: an offscreen framebuffer, or no graphics
    cuda_gl             CUDA-OpenGL interop: a raster made on a CUDA GPU copied into the presenter on the GPU
    monitors            the monitors a raster can be shown on (glfw), and choosing one
    quilt_sources       quilt images and videos to play: grids, the quilt -> views mapping, a bounded frame reader
    quilt_player        quilt playback on the panel (GL encoder into the presenter, CPU fallback), paced, with keys
    loop                the avatar pipeline frame by frame: drive -> render -> encode -> present
    session             the pipeline set up from plain options: what ``play`` and ``render`` run
    live                ``play_avatar``: the live loop, with per-stage timings
    offline             ``render_avatar``: the pipeline offline, to PNG rasters or a lossless video

Judging an avatar for the panel
    side_metrics        the LentiAvatar side-view metrics of one view (O_alpha ... E_c), the crop
    mesh_raster         the mesh mask: the pixels of each view the avatar's mesh covers
    diagnose            ``diagnose_avatars``: every view of the cone rendered and measured
    diagnose_report     the diagnostics' table, documents and figures

On OpenGL (any GPU driver, or Mesa's llvmpipe)
    gl_context          offscreen OpenGL contexts (EGL first), shared by the presenter and the gl backends
    host_views          the views stage on the host: background, edge desaturation, 8 bits, pre-compensation
    gl_views            the views stage on the GPU: background, edge desaturation, 8 bits, pre-compensation
    gl_pipeline         render, views stage and encode in one OpenGL context (``GLFrame``), timer queries
"""
