"""A user's package that plugs its own parts into searchrl through `extensions=`, touching nothing in searchrl:
an observation part (`swept`), a network that reads it (`swept_cnn`), a heuristic (`eastward`) and an obstacle law
(`pillars`). tests/test_extensions.py trains, evaluates and sweeps with them."""
