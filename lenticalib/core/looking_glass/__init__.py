"""Looking Glass formats: ``visual.json``, the vendor's lenticular rule, the models' quilts.

Importing this package loads nothing; each module imports what it needs.

    visual_file  reading a ``visual.json``: unwrapped and every field validated
    convert      ``visual.json`` imported to and exported from panel profiles
    vendor_rule  our port of the Looking Glass lenticular rule, the oracle for ``convert``
    models       Looking Glass models by serial prefix and the quilt each renders (vendor's table)
"""
