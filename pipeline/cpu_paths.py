"""One CPU code path for every numerical library the stages use, so that machines with different vector units
write the same bytes.

MKL (torch's BLAS and LAPACK), ATen (torch's own kernels) and OpenBLAS (numpy's BLAS) each pick their kernels by
CPU at run time, and on an AVX-512 machine their floats differ in the last bit from an AVX2 one; through training
(thousands of steps) that becomes another network. Importing ``pipeline`` imports this module, which pins all three
to their AVX2 paths (every x86-64 CPU since 2013 has AVX2), on x86-64 only and never over a value the environment
already holds.

Measured (2026-12-07, one run each, md5 of ``data/ingested/gaits.parquet`` against the lock made on an AVX2 path):
on an Intel AVX-512 machine, unpinned, ingest wrote other bytes; with ``MKL_CBWR=AVX2`` (MKL's conditional
numerical reproducibility) ingest, annotate and split wrote the lock's bytes; with ``ATEN_CPU_CAPABILITY=avx2``
as well, training is pinned too. ``fit_pca_gaussian`` (numpy's OpenBLAS) wrote one model with OpenBLAS's SkylakeX
kernels and another with its Haswell kernels, which are also what it runs on AMD Zen.

When each is read: MKL's and ATen's settings at torch's first computation (so torch may be imported before this
module, as long as nothing has computed); OpenBLAS's when numpy loads, so this module must be imported before numpy
(``stages/__init__.py`` imports ``pipeline`` first). In a process that loaded numpy earlier, OpenBLAS keeps the
kernels it chose.
"""

import os
import platform

PINS = {"MKL_CBWR": "AVX2", "ATEN_CPU_CAPABILITY": "avx2", "OPENBLAS_CORETYPE": "Haswell"}

if platform.machine().lower() in ("x86_64", "amd64"):
    for _name, _value in PINS.items():
        os.environ.setdefault(_name, _value)
