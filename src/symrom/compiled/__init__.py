"""Compiled execution of the learned latent dynamics (numba): the one entry point.

Everything outside this package imports from here, never from a module of it
(``tests/test_architecture.py`` checks it). It knows no model class: the fitted
model (``symrom.model``) describes itself with the typed records of
``dynamics.py`` and hands them down.

- ``TermLibrary``: a library's terms as sympy products of the state and input symbols;
  ``LatentDynamics``: a hybrid latent model (terms, Xi per phase, phase names, exact
  right-hand sides), whose ``key`` names its compiled code.
- ``table_integrator(terms, Xi)``: the term-table RK4 integrator (no compilation per model;
  the rollouts' ``table`` backend); ``rollout_windows``: many windows at once with the exact
  parameter sensitivities (the refinement's shooting); ``warm_windows``, ``start_windows_helper``:
  its kernel made ready (in numba's disk cache) in this process or in a helper process;
  ``routines``: the package's kernels every such model runs (made ready by ``symrom.experiments.warm``).
- ``generated(dynamics)``: the model's own equations as compiled code (``GeneratedFunctions``:
  RK4 integrator, LSODA's right-hand side in Python and C), cached in this process and on disk
  (``cache_dir``, ``CACHE_ENV``); ``has_build``, ``compile_seconds``.
- ``encode_states``, ``encode_inputs``, ``decode_jumps``, ``JumpViews``: a linear
  autoencoder (``LinearMaps``) over many jumps at once, a rollout's set-up and read-out.
"""

from symrom.compiled.codec import JumpViews, LinearMaps, decode_jumps, encode_inputs, encode_states
from symrom.compiled.codegen import CACHE_ENV, GeneratedFunctions, cache_dir, compile_seconds, generated, has_build
from symrom.compiled.dynamics import LatentDynamics, TermLibrary
from symrom.compiled.kernel import (
    WindowRollout,
    rollout_windows,
    routines,
    start_windows_helper,
    table_integrator,
    warm_windows,
)

__all__ = ["CACHE_ENV", "GeneratedFunctions", "JumpViews", "LatentDynamics", "LinearMaps", "TermLibrary",
           "WindowRollout", "cache_dir", "compile_seconds", "decode_jumps", "encode_inputs", "encode_states",
           "generated", "has_build", "rollout_windows", "routines", "start_windows_helper", "table_integrator",
           "warm_windows"]
