"""Pure batched torch maths over arrays (shapes in docstrings): quaternions, kinematics, geometry, features, contacts,
resampling, left-right mirroring. Knows no files, sources or stages."""
