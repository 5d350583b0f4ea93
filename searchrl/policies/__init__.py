"""Policies: the paper's network as an SB3 features extractor."""
