"""Importing this module compiles, or loads from numba's disk cache, the compiled routines every
simulation uses (``symrom.sim.engines.compiled.warm_up``, ``symrom.sim.controllers.compiled.warm_up``;
a motion's own, such as the froggy controller's, load on their first call). The worker processes'
fork server imports it, so that every worker starts with them instead of loading them on its first
tick."""

from symrom.sim.controllers.compiled import warm_up as warm_controllers
from symrom.sim.engines.compiled import warm_up as warm_engines

warm_engines()
warm_controllers(froggy=False)
