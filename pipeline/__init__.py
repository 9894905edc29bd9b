"""Emotive gait dataset pipeline: the library.

The library knows arrays, files and formats; it never reads the pipeline's params or DVC files and never knows
DVC exists.
The DVC stages in ``stages/`` wire it together and own all I/O decisions.

Importing it pins the CPU code paths of the numerical libraries (``pipeline.cpu_paths``), so that machines with
different vector units write the same bytes.
"""

from pipeline import cpu_paths  # noqa: F401  (first: OpenBLAS reads its pin when numpy loads)

__version__ = "0.1.0"
