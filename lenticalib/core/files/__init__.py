"""Files and documents: every input opened bounded, every output written atomically.

Importing this package loads nothing; each module imports what it needs.

    input_files  every input file opened bounded: a regular file (no FIFO, device) within a size cap
    atomic       atomic file output: a reader sees the old file or the new one
    outputs      output files and folders checked before the work, folders staged whole
    documents    the one document envelope (format, version), its table and its reader
    fields       checks every document reader shares: finite numbers, known key names
    arrayfile    ``.npy`` and ``.npz`` files read with every header checked first
    imageio      images as RGB numpy arrays ``(H, W, 3)``: read and written (atomically)
    video        video files opened through OpenCV, their stated frame size and count checked first
"""
