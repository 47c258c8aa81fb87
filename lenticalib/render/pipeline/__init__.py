"""The pipelines: composition only (drive -> render -> compose -> present), live, offline, quilts.

Importing this package loads nothing; each module imports what it needs.

    avatar_pipeline  ``AvatarPipeline``: one avatar frame drive -> render -> encode -> present, timed per stage
    gl_frame         render, views stage and encode in one OpenGL context (``GLFrame``), timer queries
    session          the pipeline set up from plain options: what ``play`` and ``render`` run
    live             ``play_avatar``: the live loop, with per-stage timings
    offline          ``render_avatar``: the pipeline offline, to PNG rasters or a lossless video
    encode_file      ``encode_to_file``: views + profile -> a panel raster file, in one call
    quilt_sources    quilt images and videos to play: grids, the quilt -> views mapping, a bounded frame reader
    quilt_player     quilt playback on the panel (GL encoder into the presenter, CPU fallback), paced, with keys
"""
