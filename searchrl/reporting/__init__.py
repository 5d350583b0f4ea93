"""Tidy frames, bootstrap confidence intervals and paper comparisons for the notebooks in `analysis/`."""
