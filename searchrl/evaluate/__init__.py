"""Evaluation on the paper's Table 2/3 grid: `python -m searchrl.evaluate controller=surfing|coverage|random` or
`checkpoint=<run>/model.zip`."""
