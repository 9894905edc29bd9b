"""The 5,000-gait plan (trajectories, novel emotions, recipes) and family-agnostic synthesis with real-gait
annotation."""
