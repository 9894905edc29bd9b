"""Stick figures and plots of gaits, and what `emogait preview` shows. Draws; computes nothing the pipeline stores."""
