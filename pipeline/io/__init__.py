"""Files and formats: atomic writes, sha256, manifests, mocap readers, the gait table, BVH export. Knows bytes and
schemas, not what gaits mean."""
