"""Algorithms behind the SLAM course workbook: one module per course concept (``helpers.camera``,
``helpers.gaussian``, ``helpers.association``, ``helpers.graph``, …), so a student can guess where a thing lives.
The layers and a concept map are in ``helpers/README.md``; speed and research code lives in ``helpers.advanced``.
"""

__all__ = []
