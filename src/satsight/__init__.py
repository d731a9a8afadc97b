"""satsight: physically based optical images of space objects with exact labels.

The pipeline runs one way (see ``docs/design.md``)::

    scenario -> poses -> scene -> lighting -> render -> sensor -> dataset

All quantities are SI inside; non-SI units appear only at the edges and then in names
(``distance_km``, ``pixel_pitch_um``).
"""

__version__ = "0.1.0"
