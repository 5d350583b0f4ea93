"""Controllers: trained policies and heuristics (searchrl/controllers/registry.py) behind one batched
interface, `reset(state, mask)` then `act(state, maps, vector) -> (K, N) actions`."""
