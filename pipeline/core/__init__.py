"""The pipeline's vocabulary: the canonical skeleton, the emotions, the column table. Knows no files but the
skeleton's."""
