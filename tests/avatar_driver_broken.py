"""A driver module that fails when imported (tests/test_rig.py checks the one-line error)."""

raise RuntimeError("the FLAME model file is missing\nsecond line that must not reach the user")
