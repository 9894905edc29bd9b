"""The audit of any published directory: problems, label distributions, recognisability, the HTML report."""
