"""Mocap files -> canonical 60-frame gait windows: the file screen, retargeting, marker rules, the dask run and its
report."""
