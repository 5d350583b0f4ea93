"""Training app: `python -m searchrl.train +model=<a|b|c|diagonal>` (Hydra)."""
