"""Emotive gait dataset pipeline: the library.

The library knows arrays, files and formats; it never reads the pipeline's params or DVC files and never knows
DVC exists.
The DVC stages in ``stages/`` wire it together and own all I/O decisions.

Importing it pins the CPU code paths of torch's numerical kernels, so that machines with different vector units
run the same code: MKL (torch's BLAS and LAPACK) and ATen (its own kernels) each pick theirs by CPU, and on an
AVX-512 machine their floats differ in the last bit from an AVX2 one. Measured on 2026-12-07 on an AVX-512 machine
(one run each): unpinned, it wrote another ``data/ingested/gaits.parquet`` than the committed lock (made on an AVX2
path); with ``MKL_CBWR=AVX2`` (MKL's conditional numerical reproducibility) ingest, annotate and split wrote the
lock's bytes, with ``ATEN_CPU_CAPABILITY=avx2`` as well. Training gave three different checkpoints for the three
settings (unpinned, MKL pinned, both pinned), none the lock's: the training machine's ATen path is not known, so
cross-machine training is pinned from now on, not shown. Both settings are read at the first call, so this works
when torch was imported first, as long as nothing has computed yet. A value already in the environment wins.
"""

import os

for _name, _value in (("MKL_CBWR", "AVX2"), ("ATEN_CPU_CAPABILITY", "avx2")):
    os.environ.setdefault(_name, _value)

__version__ = "0.1.0"
