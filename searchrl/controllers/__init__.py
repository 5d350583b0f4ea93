"""Controllers: trained policies and heuristics (information surfing, coverage, random walk) behind one batched
interface, `reset(state, mask)` then `act(state, maps, vector) -> (K, N) actions`."""
