"""Imported by the worker processes' fork server (``generate._preload``): loads every compiled
simulation routine numba's disk cache holds (``warm.load_cached``), so that every worker starts
with them; ``generate`` has compiled those its jumps need before it starts the workers."""

from symrom.sim.generation.warm import load_cached

load_cached()
