"""Importing this module compiles, or loads from numba's disk cache, the simulation's compiled
routines (``symrom.sim.compiled.warm_up``). The worker processes' fork server imports it, so
that every worker starts with them instead of loading them on its first tick."""

from symrom.sim.compiled import warm_up

warm_up()
