"""Control sources: where the control vectors that drive an avatar come from, one registry by spec.

Importing this package loads nothing; each module imports what it needs.

    sources  control sources by spec: the registry (``CONTROL_SOURCES``) and ``open_controls``
    files    control files (``.npz``, ``.csv``, ``.jsonl``): read, validated, played back
    records  one JSON control record, as control files and live streams carry it
    streams  live and built-in sources: the demo motion, JSON lines on stdin or UDP
"""
