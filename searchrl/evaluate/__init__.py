"""Evaluation on the paper's Table 2/3 grid: `python -m searchrl.evaluate controller=<heuristic>` or
`checkpoint=<run>/model.zip`."""
