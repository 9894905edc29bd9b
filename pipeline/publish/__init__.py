"""The published directory: table, dataset card, Croissant, PROV-JSON (from a plain stage graph), files and checks."""
