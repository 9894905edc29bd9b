"""The generator's evaluation on held-out gaits: protocols, which gaits, acceptance, the report and plots."""
