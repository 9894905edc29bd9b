"""The PCA + Gaussian expressive walk family (seed 001, Tilmanne & Dutoit): walk cycles of the real train clips
(``cycles``), a PCA basis of whole cycles and per-emotion Gaussian models of their scores and durations
(``model``)."""
