"""DVC stage entry points: each reads params.yaml, calls the library, and writes its declared outputs."""

import pipeline  # noqa: F401  (before anything loads numpy: the library's CPU pins, pipeline.cpu_paths)
