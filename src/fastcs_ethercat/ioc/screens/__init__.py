"""Phoebus screens of the served tree: the chain as the bus runs it."""
