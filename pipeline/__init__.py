"""Emotive gait dataset pipeline: the library.

The library knows arrays, files and formats; it never reads the pipeline's params or DVC files and never knows
DVC exists.
The DVC stages in ``stages/`` wire it together and own all I/O decisions.
"""

__version__ = "0.1.0"
